"""Storyboard sketches: strokes on a canvas -> the 2D keypose and trajectories of
:func:`physlab.motion.generate` (Sketch2Anim Sec. 3, supp. G).

A :class:`Sketch` holds what a person drew in a known :class:`~physlab.motion.camera.Camera`
view, in canvas pixels (``x`` right, ``y`` down): *pose* strokes (a stick figure: a circle for
the head, a line for the body, one line per limb — or one line for both arms or both legs)
and *trajectory* strokes (a joint's path, drawn in another colour), plus the action word.

**Joints from the drawing.** Sketch2Anim detects the 2D keypose with Sketch2Pose, whose
weights are not available here. The CPU substitute, :class:`TemplateSnapper`, snaps the
22-joint template (:func:`template_pose`) to the strokes by rules: the closed stroke is the
head, the open stroke nearest below it the spine, strokes starting near the top of the spine
are arms and near its bottom legs (a stroke through the body is split there), left and right
are told apart by the camera (the character's left is on the picture's right in a front
view); joints sit along each limb at the template's bone-length fractions; limbs not drawn
come from the template. A person then drags joints that came out wrong (the canvas widget).
Any callable ``detector(strokes, camera, size) -> (22, 2)`` pixel joints can replace it (the
seam for a learned detector such as Sketch2Pose).

**Strokes to trajectories.** A trajectory stroke belongs to the trajectory joint
(:data:`~physlab.motion.dataset.TRAJECTORY_JOINT_NAMES`) nearest to its start or end; if its
*start* is the nearer end, the motion begins at the keypose (``keypose_at="first"``), if its
*end*, the motion ends there (``"last"``). It is resampled to ``frames`` points uniformly by
arc length, or (``by_speed=True``, supp. G speed control) uniformly in drawing time, so that
a stroke drawn slowly where the motion should be slow gives a slow motion there.

**Pixels to normalised units** (:meth:`Sketch.pixel_frame`): the drawn figure's size fixes
the pixels per unit (its bones against the template's bones seen by the camera), and its
pelvis is placed where the canonical frame-0 pelvis ``(0, h, 0)`` projects (for
``"last"``, the start of a pelvis stroke over the whole clip, if there is one).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from physlab._io import JsonDocument

from .camera import Camera, from_pixels
from .dataset import TRAJECTORY_JOINT_NAMES, TRAJECTORY_JOINTS
from .skeleton import JOINT_NAMES, PARENTS, topological_order

__all__ = ["Stroke", "Sketch", "TemplateSnapper", "template_pose", "resample_stroke",
           "attach_trajectories", "keypose_from_strokes", "sketch_from_png", "STROKE_KINDS",
           "SKETCH_VERSION"]

#: Kinds of strokes.
STROKE_KINDS = ("pose", "trajectory")
#: Version of the JSON format of :meth:`Sketch.save`.
SKETCH_VERSION = 1

# Template: bone (named by its child joint) -> (direction in the canonical frame, length m).
# Lengths are the median bone lengths of the Bandai-Namco clips after retargeting
# (data/motion/lesson_windows.npz); directions give a relaxed standing pose facing +z
# (left = +x), arms hanging slightly away from the body.
_TEMPLATE_BONES = {
    "left_hip": ((1.0, -0.35, 0.0), 0.068), "right_hip": ((-1.0, -0.35, 0.0), 0.068),
    "spine1": ((0.0, 1.0, 0.0), 0.157),
    "left_knee": ((0.03, -1.0, 0.0), 0.391), "right_knee": ((-0.03, -1.0, 0.0), 0.391),
    "spine2": ((0.0, 1.0, 0.0), 0.090),
    "left_ankle": ((0.0, -1.0, -0.03), 0.410), "right_ankle": ((0.0, -1.0, -0.03), 0.410),
    "spine3": ((0.0, 1.0, 0.0), 0.082),
    "left_foot": ((0.0, -0.45, 1.0), 0.118), "right_foot": ((0.0, -0.45, 1.0), 0.118),
    "neck": ((0.0, 1.0, 0.0), 0.082),
    "left_collar": ((1.0, 0.35, 0.0), 0.069), "right_collar": ((-1.0, 0.35, 0.0), 0.069),
    "head": ((0.0, 1.0, 0.25), 0.065),
    "left_shoulder": ((1.0, -0.1, 0.0), 0.053), "right_shoulder": ((-1.0, -0.1, 0.0), 0.053),
    "left_elbow": ((0.2, -1.0, 0.0), 0.243), "right_elbow": ((-0.2, -1.0, 0.0), 0.243),
    "left_wrist": ((0.1, -1.0, 0.1), 0.223), "right_wrist": ((-0.1, -1.0, 0.1), 0.223),
}
_PELVIS_HEIGHT = 0.92
_J = {n: i for i, n in enumerate(JOINT_NAMES)}


def template_pose():
    """The ``(22, 3)`` standing template (m, canonical frame: pelvis above the origin, facing
    ``+z``, feet on ``y ≈ 0``) that :class:`TemplateSnapper` fits to a drawing."""
    x = np.zeros((len(JOINT_NAMES), 3))
    x[0] = (0.0, _PELVIS_HEIGHT, 0.0)
    for j in topological_order(PARENTS):
        if PARENTS[j] >= 0:
            d, length = _TEMPLATE_BONES[JOINT_NAMES[j]]
            d = np.asarray(d, dtype=float)
            x[j] = x[PARENTS[j]] + length * d / np.linalg.norm(d)
    x[:, 1] -= x[:, 1].min()
    return x


# ----------------------------------------------------------------------------- strokes


@dataclass
class Stroke:
    """One stroke in canvas pixels.

    points : (n, 2) float array, ``x`` right, ``y`` down, in drawing order.
    kind : ``"pose"`` (stick figure) or ``"trajectory"`` (a joint's path).
    times : None or (n,) float array of seconds since the stroke began (non-decreasing),
        for speed control.
    """
    points: np.ndarray
    kind: str = "pose"
    times: np.ndarray | None = None

    def __post_init__(self):
        if self.kind not in STROKE_KINDS:
            raise ValueError(f"Stroke kind must be one of {STROKE_KINDS}, got {self.kind!r}")
        p = np.asarray(self.points, dtype=float)
        if p.ndim != 2 or p.shape[1] != 2 or len(p) < 1:
            raise ValueError(f"Stroke points must have shape (n, 2) with n >= 1, got "
                             f"{p.shape}")
        if not np.all(np.isfinite(p)):
            raise ValueError("Stroke points contain NaN or inf")
        self.points = p
        if self.times is not None:
            t = np.asarray(self.times, dtype=float)
            if t.shape != (len(p),) or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
                raise ValueError(f"Stroke times must be None or a non-decreasing ({len(p)},) "
                                 f"array of finite seconds, got shape {t.shape}")
            self.times = t

    @property
    def length(self):
        """Arc length in pixels."""
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())

    def to_dict(self):
        d = {"kind": self.kind, "points": np.round(self.points, 2).tolist()}
        if self.times is not None:
            d["times"] = np.round(self.times, 4).tolist()
        return d


def _arc(points):
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(seg)])


def _at(points, fraction):
    """Point at ``fraction`` (0..1) of the arc length of a polyline."""
    s = _arc(points)
    if s[-1] <= 0:
        return points[0].copy()
    return np.array([np.interp(fraction * s[-1], s, points[:, k]) for k in range(2)])


def resample_stroke(points, n, times=None):
    """``(n, 2)`` points along a polyline: uniformly by arc length, or uniformly in time when
    ``times`` (seconds, non-decreasing) are given (supp. G speed control: where the stroke was
    drawn slowly, the samples crowd, and the motion goes slowly there)."""
    p = np.asarray(points, dtype=float)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be an integer >= 1, got {n!r}")
    if len(p) == 1:
        return np.repeat(p, n, axis=0)
    if times is not None:
        t = np.asarray(times, dtype=float)
        if t[-1] > t[0]:
            q = np.linspace(t[0], t[-1], n)
            return np.stack([np.interp(q, t, p[:, k]) for k in range(2)], axis=1)
    s = _arc(p)
    q = np.linspace(0.0, s[-1], n)
    return np.stack([np.interp(q, s, p[:, k]) for k in range(2)], axis=1)


# ----------------------------------------------------------------------------- joints


def _closed(stroke):
    p = stroke.points
    return len(p) >= 5 and np.linalg.norm(p[0] - p[-1]) < 0.3 * max(stroke.length, 1e-9)


def _split_at(points, anchor):
    """Split a polyline at its point nearest to ``anchor`` if that point is inside it (one
    line drawn through the body for both arms or both legs); each part runs from the split."""
    k = int(np.argmin(np.linalg.norm(points - anchor, axis=1)))
    n = len(points)
    if 0.15 * n < k < 0.85 * n:
        return [points[k::-1], points[k:]]
    return [points if np.linalg.norm(points[0] - anchor) <= np.linalg.norm(points[-1] - anchor)
            else points[::-1]]


def _fractions(names):
    """Cumulative fractions of a chain of template bones (by their child joints)."""
    lengths = np.array([_TEMPLATE_BONES[n][1] for n in names])
    return np.cumsum(lengths) / lengths.sum()


def _spine_score(points, head):
    """Lower = more like the body line: one end at the head, the other straight below it,
    long vertically."""
    d = np.linalg.norm(points[[0, -1]] - head, axis=1)
    far = points[0] if d[0] > d[1] else points[-1]
    return (d.min() + abs(far[0] - head[0])) / max(np.ptp(points[:, 1]), 1e-6)


def keypose_from_strokes(strokes, camera, size=None):
    """``(22, 2)`` pixel joints of a stick figure drawn as pose strokes (module docstring:
    the rules of :class:`TemplateSnapper`). ValueError if there is no pose stroke."""
    pose = [s for s in strokes if s.kind == "pose"]
    if not pose:
        raise ValueError("the sketch has no pose strokes: draw a stick figure (head circle, "
                         "body line, limbs) in the pose colour, or give the joints")
    if not isinstance(camera, Camera):
        raise TypeError(f"camera must be a physlab.motion.camera.Camera, got {camera!r}")
    tpl = camera.project(template_pose())                                  # (22, 2) units
    tpl_px = np.stack([tpl[:, 0], -tpl[:, 1]], axis=1)                     # y down
    heads = [s for s in pose if _closed(s)]
    lines = [s.points for s in pose if not _closed(s) and len(s.points) >= 2]
    head = heads[0].points.mean(axis=0) if heads else None
    radius = (np.linalg.norm(heads[0].points - head, axis=1).mean() if heads else None)
    joints = np.full((len(JOINT_NAMES), 2), np.nan)
    spine = None
    if lines:
        if head is not None:
            score = [_spine_score(p, head) for p in lines]
        else:                                             # the most vertical, longest line
            score = [-np.ptp(p[:, 1]) for p in lines]
        spine = lines.pop(int(np.argmin(score)))
        top_first = (np.linalg.norm(spine[0] - head) < np.linalg.norm(spine[-1] - head)
                     if head is not None else spine[0, 1] < spine[-1, 1])
        spine = spine[::-1] if top_first else spine                        # pelvis -> neck
        chain = ("spine1", "spine2", "spine3", "neck")
        joints[_J["pelvis"]] = spine[0]
        for name, f in zip(chain, _fractions(chain)):
            joints[_J[name]] = _at(spine, f)
        if head is not None:
            joints[_J["head"]] = head
        else:
            up = joints[_J["neck"]] - joints[_J["spine3"]]
            joints[_J["head"]] = joints[_J["neck"]] + up * (0.065 / 0.082)
    # pixels per template unit, from the body drawn so far (or the head circle)
    if spine is not None:
        drawn = np.linalg.norm(joints[_J["neck"]] - joints[_J["pelvis"]])
        ref = np.linalg.norm(tpl_px[_J["neck"]] - tpl_px[_J["pelvis"]])
    elif radius is not None:
        drawn, ref = radius, 0.1 * camera.scale
    else:
        drawn, ref = 1.0, 1.0 / (0.4 * (size[1] if size else 400) / 1.7)
    k = drawn / max(ref, 1e-9)
    if spine is None:                      # no body line: the template under the head
        anchor = head if head is not None else np.mean(np.concatenate(
            [s.points for s in pose]), axis=0)
        joints = k * (tpl_px - tpl_px[_J["head"]]) + anchor
        return joints
    neck, pelvis = joints[_J["neck"]], joints[_J["pelvis"]]
    limbs = {"arm": [], "leg": []}
    for p in lines:
        d_top = min(np.linalg.norm(p[[0, -1]] - neck, axis=1).min(),
                    np.linalg.norm(p - neck, axis=1).min())
        d_bot = min(np.linalg.norm(p[[0, -1]] - pelvis, axis=1).min(),
                    np.linalg.norm(p - pelvis, axis=1).min())
        part = "arm" if d_top <= d_bot else "leg"
        limbs[part] += _split_at(p, neck if part == "arm" else pelvis)
    # the character's left is where the camera sees +x
    left_dir = camera.rotation[0, 0]
    side_sign = 1.0 if left_dir >= 0 else -1.0
    for part, chains in (("arm", (("collar", "shoulder", "elbow", "wrist"),)),
                         ("leg", (("hip", "knee", "ankle", "foot"),))):
        found = sorted(limbs[part], key=lambda q: side_sign * q[-1, 0])[-2:]    # right, left
        sides = (("right", "left") if len(found) == 2 else
                 (("left",) if side_sign * (found[0][-1, 0] - (neck if part == "arm" else
                                                               pelvis)[0]) > 0 else ("right",))
                 if found else ())
        names = chains[0]
        for side, q in zip(sides, found):
            chain = [f"{side}_{n}" for n in names]
            if part == "arm":   # collar on the way from the neck to the shoulder (start)
                joints[_J[chain[1]]] = q[0]
                joints[_J[chain[0]]] = 0.5 * (neck + q[0])
                arm = ("_elbow", "_wrist")
                fr = _fractions([side + a for a in arm])
                for a, f in zip(arm, fr):
                    joints[_J[side + a]] = _at(q, f)
            else:               # hip a little way along the stroke, foot at its end
                tail = [f"{side}_{n}" for n in ("hip", "knee", "ankle", "foot")]
                fr = _fractions(tail)
                for name, f in zip(tail, fr):
                    joints[_J[name]] = _at(q, f)
    # limbs not drawn: the template's, placed at the drawn body
    missing = np.isnan(joints[:, 0])
    if missing.any():
        fill = k * (tpl_px - tpl_px[_J["pelvis"]]) + pelvis
        for j in topological_order(PARENTS):
            if missing[j]:
                p = PARENTS[j]
                joints[j] = joints[p] + (fill[j] - fill[p])
    return joints


class TemplateSnapper:
    """The CPU substitute for Sketch2Pose: :func:`keypose_from_strokes`. Any callable with
    this signature can be given to :meth:`Sketch.keypose` instead (e.g. a learned detector
    that reads the rendered strokes)."""

    def __call__(self, strokes, camera, size=None):
        return keypose_from_strokes(strokes, camera, size)


def attach_trajectories(strokes, joints, frames=40, by_speed=False):
    """Trajectory strokes -> ``({joint_name: (frames, 2) pixels}, keypose_at)``.

    Each stroke goes to the trajectory joint whose keypose position is nearest to one of its
    ends (module docstring); the first stroke's end decides ``keypose_at`` (``"first"`` if it
    starts at the joint, else ``"last"``) and a later stroke that disagrees is reversed to
    fit. ValueError if two strokes claim the same joint."""
    joints = np.asarray(joints, dtype=float)
    if joints.shape != (len(JOINT_NAMES), 2):
        raise ValueError(f"joints must have shape ({len(JOINT_NAMES)}, 2), got {joints.shape}")
    if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or not \
            2 <= frames <= 40:
        raise ValueError(f"frames must be an integer in 2..40 (the clip's frames), got "
                         f"{frames!r}")
    out, keypose_at = {}, None
    ends = joints[list(TRAJECTORY_JOINTS)]                                # (6, 2)
    for s in (s for s in strokes if s.kind == "trajectory"):
        p, t = s.points, s.times
        d0 = np.linalg.norm(ends - p[0], axis=1)
        d1 = np.linalg.norm(ends - p[-1], axis=1)
        at = "first" if d0.min() <= d1.min() else "last"
        j = int(np.argmin(d0 if at == "first" else d1))
        if keypose_at is None:
            keypose_at = at
        elif at != keypose_at:                  # one clip, one key frame: read it backwards
            p = p[::-1]
            t = None if t is None else t[-1] - t[::-1]
            j = int(np.argmin(d1 if at == "first" else d0))
        name = TRAJECTORY_JOINT_NAMES[j]
        if name in out:
            raise ValueError(f"two trajectory strokes start or end at the {name}; draw one "
                             f"stroke per joint")
        out[name] = resample_stroke(p, frames, t if by_speed else None)
    return out, keypose_at or "first"


# ----------------------------------------------------------------------------- sketch


@dataclass
class Sketch(JsonDocument):
    """A storyboard sketch (module docstring): ``action`` text, ``camera``, ``strokes``
    (:class:`Stroke`, canvas pixels), canvas ``size`` (width, height) px, and ``joints``
    ((22, 2) pixels; None until :meth:`keypose` snaps them or a person places them).
    ``save(path)`` / ``load(path)``: JSON (:class:`~physlab._io.JsonDocument`)."""
    JSON_VERSION = SKETCH_VERSION
    action: str = "a person walks"
    camera: Camera = field(default_factory=Camera)
    strokes: list = field(default_factory=list)
    size: tuple = (480, 480)
    joints: np.ndarray | None = None

    def __post_init__(self):
        if not isinstance(self.action, str):
            raise TypeError(f"action must be a text, got {self.action!r}")
        if not isinstance(self.camera, Camera):
            raise TypeError(f"camera must be a physlab.motion.camera.Camera, got "
                            f"{self.camera!r}")
        w, h = (int(v) for v in self.size)
        if w < 16 or h < 16:
            raise ValueError(f"size must be (width, height) >= 16 px, got {self.size!r}")
        self.size = (w, h)
        if self.joints is not None:
            j = np.asarray(self.joints, dtype=float)
            if j.shape != (len(JOINT_NAMES), 2) or not np.all(np.isfinite(j)):
                raise ValueError(f"joints must be a finite ({len(JOINT_NAMES)}, 2) array of "
                                 f"pixels, got shape {j.shape}")
            self.joints = j
        for k, s in enumerate(self.strokes):
            if not isinstance(s, Stroke):
                raise TypeError(f"strokes[{k}] must be a Stroke, got {type(s).__name__}")

    def keypose(self, detector=None):
        """Snap the joints to the pose strokes with ``detector`` (default
        :class:`TemplateSnapper`), store and return them ((22, 2) px)."""
        detector = detector or TemplateSnapper()
        j = np.asarray(detector(self.strokes, self.camera, self.size), dtype=float)
        if j.shape != (len(JOINT_NAMES), 2) or not np.all(np.isfinite(j)):
            raise ValueError(f"the detector must return finite ({len(JOINT_NAMES)}, 2) pixel "
                             f"joints, got shape {j.shape}")
        self.joints = j
        return j

    @property
    def has_pose(self):
        return any(s.kind == "pose" for s in self.strokes) or self.joints is not None

    def pixel_frame(self, trajectories=None, keypose_at="first"):
        """``(origin, pixels_per_unit)`` of :func:`~physlab.motion.camera.from_pixels` for this
        sketch (module docstring). Without a figure: the canvas centre, 1.7 m = 40 % of the
        canvas height."""
        tpl = self.camera.project(template_pose())
        if self.joints is not None:
            child = np.arange(1, len(JOINT_NAMES))
            drawn = np.linalg.norm(self.joints[child] - self.joints[PARENTS[1:]], axis=1).sum()
            ref = np.linalg.norm(tpl[child] - tpl[PARENTS[1:]], axis=1).sum()
            ppu = drawn / max(ref, 1e-9)
            pelvis0 = self.joints[0]
            if keypose_at == "last" and trajectories and "pelvis" in trajectories \
                    and len(trajectories["pelvis"]) == 40:
                pelvis0 = trajectories["pelvis"][0]
        else:
            ppu = 0.4 * self.size[1] / 1.7
            pelvis0 = np.array(self.size, dtype=float) / 2
            if trajectories and "pelvis" in trajectories:
                pelvis0 = trajectories["pelvis"][0]
        p0 = self.camera.project(np.array([0.0, template_pose()[0, 1], 0.0]))  # (2,) units
        origin = np.array([pelvis0[0] - ppu * p0[0], pelvis0[1] + ppu * p0[1]])
        return origin, float(ppu)

    def trajectories_px(self, frames=40, by_speed=False):
        """:func:`attach_trajectories` of the trajectory strokes to the joints (to the canvas
        centre while there are none): ``({joint_name: (frames, 2) px}, keypose_at)``."""
        anchor = (self.joints if self.joints is not None else
                  np.tile(np.array(self.size, dtype=float) / 2, (len(JOINT_NAMES), 1)))
        return attach_trajectories(self.strokes, anchor, frames, by_speed)

    def conditions(self, frames=40, by_speed=False, detector=None):
        """The keywords of :func:`physlab.motion.generate` for this sketch: ``action``,
        ``keypose_2d`` ((22, 2) normalised units or None), ``trajectories_2d``, ``camera``,
        ``keypose_at``. Snaps the joints first if there are pose strokes but no joints."""
        if self.joints is None and any(s.kind == "pose" for s in self.strokes):
            self.keypose(detector)
        trajs_px, keypose_at = self.trajectories_px(frames, by_speed)
        if self.joints is None and not trajs_px:
            raise ValueError("the sketch is empty: draw a stick figure and/or trajectory "
                             "strokes")
        origin, ppu = self.pixel_frame(trajs_px, keypose_at)
        key = None if self.joints is None else from_pixels(self.joints, origin, ppu)
        trajs = {k: from_pixels(v, origin, ppu) for k, v in trajs_px.items()}
        return {"action": self.action, "keypose_2d": key, "trajectories_2d": trajs or None,
                "camera": self.camera, "keypose_at": keypose_at}

    # -- JSON
    def to_dict(self):
        return {"version": SKETCH_VERSION, "action": self.action,
                "camera": self.camera.to_dict(), "size": list(self.size),
                "strokes": [s.to_dict() for s in self.strokes],
                "joints": None if self.joints is None else np.round(self.joints, 2).tolist()}

    @classmethod
    def from_dict(cls, d, source="sketch"):
        cls.check_document(d, source)
        try:
            strokes = []
            for k, s in enumerate(d.get("strokes", [])):
                try:
                    strokes.append(Stroke(points=np.asarray(s["points"], dtype=float),
                                          kind=s.get("kind", "pose"), times=s.get("times")))
                except (KeyError, TypeError, ValueError) as e:
                    raise ValueError(f"strokes[{k}]: {e}") from None
            return cls(action=d.get("action", ""), camera=Camera.from_dict(d.get("camera", {})),
                       strokes=strokes, size=tuple(d.get("size", (480, 480))),
                       joints=d.get("joints"))
        except (TypeError, ValueError) as e:
            raise ValueError(f"{source}: {e}") from None


# ----------------------------------------------------------------------------- PNG


def _mask(img, color, tol):
    rgb = img[..., :3].astype(float)
    m = np.linalg.norm(rgb - np.asarray(color, dtype=float), axis=-1) <= tol
    if img.shape[-1] == 4:
        m &= img[..., 3] > 127
    return m


def _trace(mask):
    """Polylines along the one-pixel skeleton of a mask: each branch between end and
    junction pixels (8-neighbours), in order."""
    from skimage.morphology import skeletonize

    sk = skeletonize(mask)
    pts = {tuple(p) for p in np.argwhere(sk)}
    nb = {p: [(p[0] + dy, p[1] + dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1)
              if (dy or dx) and (p[0] + dy, p[1] + dx) in pts] for p in pts}
    nodes = {p for p, n in nb.items() if len(n) != 2}
    seen, lines = set(), []

    def walk(a, b):
        path = [a, b]
        while path[-1] not in nodes:
            nxt = [q for q in nb[path[-1]] if q != path[-2] and (path[-1], q) not in seen]
            if not nxt:
                break
            seen.add((path[-1], nxt[0]))
            seen.add((nxt[0], path[-1]))
            path.append(nxt[0])
            if path[-1] == path[0]:
                break
        return path

    for a in sorted(nodes) + sorted(pts - nodes):         # loops without nodes come last
        for b in nb[a]:
            if (a, b) in seen:
                continue
            seen.add((a, b))
            seen.add((b, a))
            path = walk(a, b)
            if len(path) >= 3:
                lines.append(np.array([(x, y) for y, x in path], dtype=float))
    return lines


def sketch_from_png(path, action="a person walks", camera=None, pose_color=(0, 0, 0),
                    trajectory_color=(220, 0, 0), tolerance=80):
    """A :class:`Sketch` from a PNG of a stick figure (``pose_color``) and trajectory strokes
    (``trajectory_color``) on a light background.

    The pixels of each colour are thinned to one-pixel lines and traced into branches
    (:func:`_trace`); a PNG has no drawing order, so a trajectory is taken to start at the
    figure's joint it touches (``keypose_at="first"``). The joints are snapped by
    :meth:`Sketch.keypose`; check them (and drag them in the canvas) before generating.
    ValueError naming the file if it cannot be read or holds no pose-coloured pixels."""
    import imageio.v3 as iio

    path = Path(path)
    try:
        img = np.asarray(iio.imread(path))
    except Exception as e:                                  # imageio raises many kinds
        raise ValueError(f"{path}: cannot read the image ({e})") from None
    if img.ndim == 2:
        img = np.stack([img] * 3, axis=-1)
    if img.dtype != np.uint8:
        img = (255 * img.astype(float) / max(float(img.max()), 1.0)).astype(np.uint8)
    pose = _mask(img, pose_color, tolerance)
    if pose.sum() < 20:
        raise ValueError(f"{path}: no stick figure in the pose colour {tuple(pose_color)} "
                         f"(found {int(pose.sum())} pixels); pass pose_color=")
    shortest = max(6.0, 0.03 * max(img.shape[:2]))      # bits of the traced junctions
    strokes = [Stroke(p, "pose") for p in _trace(pose) if _arc(p)[-1] >= shortest]
    strokes += [Stroke(p, "trajectory") for p in _trace(_mask(img, trajectory_color, tolerance))
                if _arc(p)[-1] >= shortest]
    sk = Sketch(action=action, camera=camera or Camera(), strokes=strokes,
                size=(img.shape[1], img.shape[0]))
    sk.keypose()
    # without drawing order: a trajectory runs away from the joint it touches
    ends = sk.joints[list(TRAJECTORY_JOINTS)]
    for s in sk.strokes:
        if s.kind == "trajectory" and (np.linalg.norm(ends - s.points[-1], axis=1).min()
                                       < np.linalg.norm(ends - s.points[0], axis=1).min()):
            s.points = s.points[::-1].copy()
    return sk
