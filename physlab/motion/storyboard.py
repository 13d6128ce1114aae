"""Storyboards: several sketch frames become one animation (Sketch2Anim Secs. 3 and 6,
Fig. 1, supp. D).

A :class:`Storyboard` is a list of :class:`StoryboardFrame`: an action text plus any of a
keypose and joint trajectories, in 3D (metres, the clip's canonical frame) or drawn in 2D in
a :class:`~physlab.motion.camera.Camera` view (normalised image units; a frame may also keep
the :class:`~physlab.motion.sketch.Sketch` it came from, for display: its conditions are the
ones :meth:`StoryboardFrame.from_sketch` read from it).
:func:`storyboard_to_motion` generates one clip per frame with
:func:`~physlab.motion.generate` (seed ``seed + i`` for frame ``i``), places each clip after
the previous one and joins them with ``transition`` frames (:mod:`physlab.motion.blend`,
Sketch2Anim's DDIM-inversion blending by default). As in the paper, frames are drawn
"without global placements": each clip starts at its own origin and the placement follows
the previous clip's end position and heading.

JSON (:meth:`Storyboard.save` / :meth:`Storyboard.load`, atomic writes, errors name the file
and the frame)::

    {"version": 1, "title": "...", "camera": {...} | null,
     "frames": [{"action": "a person walks", "keypose_at": "first",
                 "keypose_2d": [[u, v] x 22] | null, "trajectories_2d": {"pelvis": [[u, v], ...]},
                 "keypose_3d": ..., "trajectories_3d": ..., "camera": {...} | null,
                 "sketch": {Sketch JSON} | null}, ...]}
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from physlab._io import JsonDocument

from .blend import BLEND_METHODS, TRANSITION, blend, place_after
from .camera import Camera
from .conditions import KEYPOSE_AT, N_FRAMES, build_condition, build_sketch

__all__ = ["StoryboardFrame", "Storyboard", "StoryboardAnimation", "storyboard_to_motion",
           "animate_storyboard", "STORYBOARD_VERSION"]

#: Version of the JSON format of :meth:`Storyboard.save`.
STORYBOARD_VERSION = 1


def _array_or_none(v, name, cols, required=False):
    if v is None:
        if required:
            raise ValueError(f"{name} must be a (k, {cols}) array, got None")
        return None
    try:
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array, got {type(v).__name__}") from None
    if a.ndim != 2 or a.shape[1] != cols:
        raise ValueError(f"{name} must have shape (k, {cols}), got {a.shape}")
    return a


def _trajs_or_none(d, name, cols):
    if d is None or (isinstance(d, dict) and not d):
        return None
    if not isinstance(d, dict):
        raise ValueError(f"{name} must be a dict {{joint_name: (t_r, {cols}) array}}, got "
                         f"{type(d).__name__}")
    return {str(k): _array_or_none(v, f"{name}[{k!r}]", cols, required=True)
            for k, v in d.items()}


@dataclass
class StoryboardFrame:
    """One storyboard frame: the action text and optional conditions of one clip.

    action : str, e.g. ``"a person walks"``.
    keypose_2d : None or (22, 2) normalised image units in ``camera``'s view;
    trajectories_2d : None or ``{joint_name: (t_r, 2)}``; keypose_3d : None or (22, 3) m;
    trajectories_3d : None or ``{joint_name: (t_r, 3)}`` m (canonical clip frame);
    camera : None (the storyboard's camera) or a :class:`~physlab.motion.camera.Camera`;
    keypose_at : ``"first"`` | ``"last"`` (:func:`~physlab.motion.generate`);
    sketch : None or the :class:`~physlab.motion.sketch.Sketch` the frame was drawn as
        (:meth:`from_sketch`); kept for display and editing.

    A condition given both in 2D and in 3D, an unknown trajectory joint, a wrong shape, or 2D
    conditions without any camera (neither the frame's nor the storyboard's) are errors
    naming the field (checked when the frame is made and again in the storyboard).
    """
    action: str
    keypose_2d: np.ndarray | None = None
    trajectories_2d: dict | None = None
    keypose_3d: np.ndarray | None = None
    trajectories_3d: dict | None = None
    camera: Camera | None = None
    keypose_at: str = "first"
    sketch: object = None

    def __post_init__(self):
        if not isinstance(self.action, str) or not self.action.strip():
            raise ValueError(f"action must be a non-empty text such as 'a person walks', got "
                             f"{self.action!r}")
        if self.keypose_at not in KEYPOSE_AT:
            raise ValueError(f"keypose_at must be 'first' or 'last', got {self.keypose_at!r}")
        if self.camera is not None and not isinstance(self.camera, Camera):
            raise TypeError(f"camera must be a physlab.motion.camera.Camera or None, got "
                            f"{self.camera!r}")
        self.keypose_2d = _array_or_none(self.keypose_2d, "keypose_2d", 2)
        self.keypose_3d = _array_or_none(self.keypose_3d, "keypose_3d", 3)
        self.trajectories_2d = _trajs_or_none(self.trajectories_2d, "trajectories_2d", 2)
        self.trajectories_3d = _trajs_or_none(self.trajectories_3d, "trajectories_3d", 3)
        self.check(self.camera or Camera())    # the camera may come from the storyboard

    @classmethod
    def from_sketch(cls, sketch, detector=None):
        """The frame of a :class:`~physlab.motion.sketch.Sketch` (its action, camera and
        :meth:`~physlab.motion.sketch.Sketch.conditions`), keeping the sketch."""
        c = sketch.conditions(detector=detector)
        return cls(action=c["action"], keypose_2d=c["keypose_2d"],
                   trajectories_2d=c["trajectories_2d"], camera=c["camera"],
                   keypose_at=c["keypose_at"], sketch=sketch)

    @property
    def has_2d(self):
        return self.keypose_2d is not None or bool(self.trajectories_2d)

    def check(self, camera=None):
        """Validate the conditions (shapes, joint names, 2D vs 3D, camera) through the
        builders :func:`~physlab.motion.conditions.build_condition` /
        :func:`~physlab.motion.conditions.build_sketch`; ``camera`` is used when the frame
        has none. Raises ValueError / TypeError."""
        c3 = build_condition(self.keypose_3d, self.keypose_at, self.trajectories_3d)
        c2 = build_sketch(self.keypose_2d, self.keypose_at, self.trajectories_2d,
                          self.camera or camera)
        both = (c3["traj_mask"] & c2["traj_mask"]).any(axis=0)
        if both.any() or (c3["has_keypose"] and c2["has_keypose"]):
            raise ValueError("give each condition in 3D or in 2D, not both (keypose_2d and "
                             "keypose_3d, or the same joint in trajectories_2d and "
                             "trajectories_3d)")

    def generate_kwargs(self, camera=None):
        """Keywords of :func:`~physlab.motion.generate` for this frame (``camera``: the
        storyboard's, used when the frame has none)."""
        return {"action": self.action, "keypose_2d": self.keypose_2d,
                "trajectories_2d": self.trajectories_2d, "keypose_3d": self.keypose_3d,
                "trajectories_3d": self.trajectories_3d, "keypose_at": self.keypose_at,
                "camera": (self.camera or camera) if self.has_2d else None}

    def to_dict(self):
        def arr(a):
            return None if a is None else np.round(a, 5).tolist()

        def trajs(d):
            return None if not d else {k: arr(v) for k, v in d.items()}

        return {"action": self.action, "keypose_at": self.keypose_at,
                "keypose_2d": arr(self.keypose_2d), "trajectories_2d": trajs(self.trajectories_2d),
                "keypose_3d": arr(self.keypose_3d), "trajectories_3d": trajs(self.trajectories_3d),
                "camera": None if self.camera is None else self.camera.to_dict(),
                "sketch": None if self.sketch is None else self.sketch.to_dict()}

    @classmethod
    def from_dict(cls, d, source="frame"):
        from .sketch import Sketch

        if not isinstance(d, dict):
            raise ValueError(f"{source}: expected a JSON object, got {type(d).__name__}")
        known = {"action", "keypose_at", "keypose_2d", "trajectories_2d", "keypose_3d",
                 "trajectories_3d", "camera", "sketch"}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(f"{source}: unknown keys {unknown}; a frame has {sorted(known)}")
        try:
            cam = d.get("camera")
            sk = d.get("sketch")
            return cls(action=d.get("action", ""), keypose_at=d.get("keypose_at", "first"),
                       keypose_2d=d.get("keypose_2d"), trajectories_2d=d.get("trajectories_2d"),
                       keypose_3d=d.get("keypose_3d"), trajectories_3d=d.get("trajectories_3d"),
                       camera=None if cam is None else Camera.from_dict(cam),
                       sketch=None if sk is None else Sketch.from_dict(sk, f"{source}.sketch"))
        except (TypeError, ValueError) as e:
            raise ValueError(f"{source}: {e}") from None


@dataclass
class Storyboard(JsonDocument):
    """Frames in order (:class:`StoryboardFrame`), a ``camera`` for frames drawn without
    their own, and a ``title``. At least one frame. ``save(path)`` / ``load(path)``: JSON
    (:class:`~physlab._io.JsonDocument`)."""
    JSON_VERSION = STORYBOARD_VERSION
    frames: list
    camera: Camera | None = None
    title: str = ""

    def __post_init__(self):
        if not isinstance(self.title, str):
            raise TypeError(f"title must be a text, got {self.title!r}")
        self.validate()

    def validate(self):
        """Check every frame against the storyboard's camera (also after frames were added
        or edited in place); errors name the frame. :func:`animate_storyboard` calls it."""
        self.frames = list(self.frames)
        if not self.frames:
            raise ValueError("a storyboard needs at least one frame")
        if self.camera is not None and not isinstance(self.camera, Camera):
            raise TypeError(f"camera must be a physlab.motion.camera.Camera or None, got "
                            f"{self.camera!r}")
        for i, f in enumerate(self.frames):
            if not isinstance(f, StoryboardFrame):
                raise TypeError(f"frames[{i}] must be a StoryboardFrame, got "
                                f"{type(f).__name__}")
            try:
                f.check(self.camera)
            except (TypeError, ValueError) as e:
                raise type(e)(f"frames[{i}] ({f.action!r}): {e}") from None

    def __len__(self):
        return len(self.frames)

    def to_dict(self):
        return {"version": STORYBOARD_VERSION, "title": self.title,
                "camera": None if self.camera is None else self.camera.to_dict(),
                "frames": [f.to_dict() for f in self.frames]}

    @classmethod
    def from_dict(cls, d, source="storyboard"):
        cls.check_document(d, source)
        frames = d.get("frames")
        if not isinstance(frames, list) or not frames:
            raise ValueError(f"{source}: 'frames' must be a non-empty list of frames")
        try:
            cam = d.get("camera")
            camera = None if cam is None else Camera.from_dict(cam)
        except (TypeError, ValueError) as e:
            raise ValueError(f"{source}: camera: {e}") from None
        parsed = [StoryboardFrame.from_dict(f, f"{source}: frames[{i}]")
                  for i, f in enumerate(frames)]
        try:
            title = d.get("title", "")
            return cls(parsed, camera=camera, title="" if title is None else title)
        except (TypeError, ValueError) as e:
            raise ValueError(f"{source}: {e}") from None


@dataclass
class StoryboardAnimation:
    """The result of :func:`animate_storyboard`.

    joints : (N, 22, 3) m, the whole animation (20 fps); clips : the generated clips
    (40, 22, 3) each, in their own canonical frame (on the common skeleton, if asked); segments : per frame, the slice of
    ``joints`` its clip occupies; transitions : per junction, the slice of the new frames;
    windows : per junction, the slice the blending changed; placements : per frame,
    ``(theta, offset)`` with ``joints[segment] ≈ R_y(theta) clip + offset`` (exact outside the
    blending windows); seconds : wall times (``generate`` per clip, ``blend`` per junction).
    """
    joints: np.ndarray
    clips: list
    segments: list
    transitions: list
    windows: list
    placements: list = field(default_factory=list)
    seconds: dict = field(default_factory=dict)

    def local(self, i, joints=None):
        """``joints`` (default: the animation's frames of clip ``i``, (n, 22, 3)) moved back
        into clip ``i``'s own frame, where its storyboard frame's conditions and camera
        live: ``R_y(−theta) (x − offset)``."""
        from .features import _rotate_y

        theta, offset = self.placements[i]
        x = self.joints[self.segments[i]] if joints is None else np.asarray(joints, float)
        return _rotate_y(x - offset, np.full(len(x), -theta))

    def frame_at(self, k):
        """Index of the storyboard frame whose clip (or the transition into it) plays at
        animation frame ``k`` (``0 <= k < len(joints)``)."""
        n = len(self.joints)
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 0 <= k < n:
            raise IndexError(f"animation frame {k!r} out of range: the animation has {n} "
                             f"frames (0..{n - 1})")
        for i, s in enumerate(self.segments):
            if k < s.stop:
                return i
        return len(self.segments) - 1


def animate_storyboard(storyboard, transition=TRANSITION, seed=0, progress=False,
                       method="inversion", checkpoint=None, blend_options=None,
                       common_skeleton=True, **generate_options):
    """Generate every frame's clip and join them (module docstring).

    Parameters
    ----------
    storyboard : :class:`Storyboard` (or a path to its JSON).
    transition : int >= 1, frames between adjacent clips (``method="concat"``: none).
    seed : int; frame ``i`` is generated with ``seed + i``.
    progress : a tqdm bar over the frames and junctions.
    method : one of :data:`~physlab.motion.blend.BLEND_METHODS`.
    checkpoint : None (the shipped generator) or a checkpoint path.
    blend_options : dict of further keywords of :func:`~physlab.motion.blend.blend`.
    common_skeleton : bool, put every clip on one set of bone lengths (the median over all
        clips; :func:`~physlab.motion.body.constrain_body`) before joining them: each
        generated clip has its own (they differ by 1–3 cm), and a blend between two skeletons
        either stretches bones or jumps where it meets the next clip (measured: 8–16 mm bone
        variation in the windows, or a 2.9 cm wrist step at the window's end).
    generate_options : further keywords of :func:`~physlab.motion.generate` (e.g.
        ``guidance_final``).

    Returns
    -------
    :class:`StoryboardAnimation`.
    """
    from .sampling import load_generator

    if isinstance(storyboard, (str, Path)):
        storyboard = Storyboard.load(storyboard)
    if not isinstance(storyboard, Storyboard):
        raise TypeError(f"storyboard must be a Storyboard or a path to its JSON, got "
                        f"{type(storyboard).__name__}")
    if method not in BLEND_METHODS:
        raise ValueError(f"method must be one of {BLEND_METHODS}, got {method!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    storyboard.validate()
    if method != "concat" and len(storyboard) > 1:    # before the clips: fail fast
        from .blend import _check_gap

        _check_gap(transition, method, N_FRAMES - 2 if method in ("inversion", "inpaint")
                   else None)
    reserved = sorted({"actions", "generator", "seed", "method", "transition"}
                      & set(blend_options or {}))
    if reserved:
        raise ValueError(f"blend_options may not set {reserved}: animate_storyboard sets them "
                         f"(use its own arguments)")
    from tqdm.auto import tqdm

    gen = load_generator(checkpoint)
    n = len(storyboard)
    with tqdm(total=2 * n - 1, disable=not progress, desc="storyboard") as bar:
        return _animate(storyboard, gen, bar, transition, seed, method, blend_options,
                        common_skeleton, generate_options)


def _animate(storyboard, gen, bar, transition, seed, method, blend_options, common_skeleton,
             generate_options):
    n = len(storyboard)
    clips, gen_s, blend_s = [], [], []
    for i, frame in enumerate(storyboard.frames):
        t0 = time.perf_counter()
        try:
            clips.append(gen(seed=int(seed) + i, **frame.generate_kwargs(storyboard.camera),
                             **generate_options))
        except (TypeError, ValueError) as e:
            raise type(e)(f"frames[{i}] ({frame.action!r}): {e}") from None
        gen_s.append(time.perf_counter() - t0)
        bar.update(1)
    if common_skeleton and n > 1:   # one character: every clip on the same bone lengths
        from .body import clip_bone_lengths, constrain_body

        lengths = clip_bone_lengths(np.concatenate(clips))
        clips = [constrain_body(c, lengths, lock=False) for c in clips]
    motion = clips[0]
    segments, transitions, windows = [slice(0, len(motion))], [], []
    placements = [(0.0, np.zeros(3))]
    opts = dict(blend_options or {})
    for i in range(1, n):
        gap = 0 if method == "concat" else transition
        placed, theta, offset = place_after(motion, clips[i], gap, return_transform=True)
        placements.append((theta, offset))
        res = blend(motion, placed, transition=gap, method=method,
                    actions=(storyboard.frames[i - 1].action, storyboard.frames[i].action),
                    generator=gen, seed=int(seed) + i, **opts)
        motion = res.joints
        transitions.append(res.transition)
        windows.append(res.window)
        segments.append(slice(res.transition.stop, len(motion)))
        blend_s.append(res.seconds)
        bar.update(1)
    return StoryboardAnimation(motion, clips, segments, transitions, windows, placements,
                               {"generate": gen_s, "blend": blend_s})


def storyboard_to_motion(storyboard, transition=TRANSITION, seed=0, progress=False, **options):
    """``(N, 22, 3)`` joints (m, 20 fps) of the whole storyboard: :func:`animate_storyboard`
    ``(...).joints`` (DESIGN.md). ``options``: its other keywords."""
    return animate_storyboard(storyboard, transition=transition, seed=seed, progress=progress,
                              **options).joints
