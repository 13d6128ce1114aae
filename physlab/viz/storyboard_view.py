"""Pictures and files of a storyboard animation: the sketches next to what came out of them
(Sketch2Anim Sec. 6, Fig. 1: storyboard frames over the generated motion).

Every storyboard frame ``i`` is drawn in its own *view*, :func:`frame_view`: the camera it was
drawn in and the 2D plane of its drawing. A frame that holds a
:class:`~physlab.motion.sketch.Sketch` is drawn as its strokes in canvas pixels (``x`` right,
``y`` down; pose black, trajectories red); a frame with conditions but no sketch as its
keypose and trajectories in normalised image units (``u`` right, ``v`` up; 3D conditions
projected by the camera); a text-only frame as a card with its action. The motion of frame
``i``'s clip is moved back into the clip's own canonical frame
(:meth:`~physlab.motion.storyboard.StoryboardAnimation.local`), where the conditions live,
and projected into the same plane (:meth:`~physlab.motion.camera.Camera.project`, then
:func:`~physlab.motion.camera.to_pixels` with the sketch's
:meth:`~physlab.motion.sketch.Sketch.pixel_frame`, exactly as the sketch canvas overlays a
generated clip). The camera is the frame's, else the storyboard's, else
:data:`DEFAULT_CAMERA` (a 3/4 view).

* :func:`storyboard_contact_sheet` — one Figure: per frame the drawing (top row) and the
  clip projected in the same view (middle row, over a faint copy of the drawing), then the
  whole animation from above and from the side (bottom row).
* :func:`sketch_overlay_frames` — per animation frame an image of the storyboard frame that
  plays with the current pose over it (PIL, fast enough for every frame).
* :func:`export_storyboard` — BVH, capsule-human GIF / MP4, overlay GIF, storyboard JSON and
  contact sheet PNG into one folder, every file written atomically.
* :func:`check_bvh` — read an exported BVH back and check it is the 22-joint skeleton of
  :mod:`physlab.motion.skeleton` with the expected frames and frame time.
"""
from __future__ import annotations

import copy
import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from physlab._io import atomic_write
from physlab.motion.camera import Camera, to_pixels
from physlab.motion.skeleton import JOINT_NAMES, KINEMATIC_CHAINS, PARENTS

__all__ = ["DEFAULT_CAMERA", "COLORS", "FRAME_COLORS", "EXPORT_FORMATS", "EXPORT_FILES",
           "FrameView", "frame_camera", "frame_view", "storyboard_contact_sheet",
           "sketch_overlay_frames", "overlay_pixel", "export_storyboard", "check_bvh",
           "resample_frames", "ANIMATION_FPS"]

#: The view of a frame that has no camera of its own and a storyboard without one: a 3/4
#: view from slightly above.
DEFAULT_CAMERA = Camera(pitch=15.0, yaw=30.0)
#: Colours (matplotlib names / hex): pose strokes, trajectory strokes, the generated motion,
#: transition frames; the same as the sketch canvas (:mod:`physlab.viz.sketch_canvas`).
COLORS = {"pose": "#000000", "trajectory": "#dc0000", "motion": "#1f77b4",
          "transition": "#999999", "sketch_faint": "#c8c8c8", "trajectory_faint": "#f0b4b4"}
#: One colour per storyboard frame in the whole-animation views (cycled; neither blue, the
#: motion, nor grey, the transitions, nor red, the trajectories).
FRAME_COLORS = ("#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#17becf")
#: File written for each format of :func:`export_storyboard`, in the order they are written.
EXPORT_FILES = {"bvh": "storyboard.bvh", "gif": "storyboard.gif", "mp4": "storyboard.mp4",
                "sketch_gif": "storyboard_sketch.gif", "json": "storyboard.json",
                "png": "storyboard_sheet.png"}
EXPORT_FORMATS = tuple(EXPORT_FILES)

#: Width / height the view of a frame has at least (its bounds are widened to it).
_MIN_ASPECT = 1.2
_BONES = np.stack([PARENTS[1:], np.arange(1, len(JOINT_NAMES))], axis=1)     # (21, 2)


def _rgb255(color):
    from matplotlib.colors import to_rgb

    return tuple(int(round(255 * c)) for c in to_rgb(color))


# ----------------------------------------------------------------------------- the view


@dataclass(frozen=True)
class FrameView:
    """How storyboard frame ``i`` is drawn (:func:`frame_view`).

    kind : ``"sketch"`` | ``"conditions"`` | ``"text"``.
    action : str. camera : the :class:`~physlab.motion.camera.Camera` of the view.
    y_down : True for canvas pixels (sketch), False for normalised image units (v up).
    units : axis unit label, ``"px"`` or ``"image units"``.
    canvas : ``(width, height)`` px of the sketch, or None.
    pose : list of ``(n, 2)`` polylines of the drawn figure (strokes, or the keypose's
        kinematic chains), view coordinates. trajectory : list of ``(n, 2)`` polylines.
    key_frame : index into the clip of the keypose (0 or last), or None without a keypose.
    frames : the animation frames ``k`` with ``frame_at(k) == i`` (its transition and clip).
    motion : ``(n, 22, 2)`` the clip (``animation.segments[i]``) projected into the view.
    bounds : ``(x0, x1, y0, y1)`` covering the canvas, the drawing and every frame of
        ``frames`` projected (view coordinates).
    origin, pixels_per_unit : the sketch's :meth:`~physlab.motion.sketch.Sketch.pixel_frame`
        (None for the other kinds).
    """
    kind: str
    action: str
    camera: Camera
    y_down: bool
    units: str
    canvas: tuple | None
    pose: list
    trajectory: list
    key_frame: int | None
    frames: range
    motion: np.ndarray
    bounds: tuple
    origin: np.ndarray | None = None
    pixels_per_unit: float | None = None

    def project(self, joints):
        """``(..., 3)`` points in the clip's canonical frame (m) -> ``(..., 2)`` view
        coordinates (canvas pixels for a sketch, else normalised image units)."""
        uv = self.camera.project(joints)
        if self.origin is None:
            return uv
        return to_pixels(uv, self.origin, self.pixels_per_unit)


def _check_pair(storyboard, animation):
    from physlab.motion.storyboard import Storyboard, StoryboardAnimation

    if not isinstance(storyboard, Storyboard):
        raise TypeError(f"storyboard must be a physlab.motion.Storyboard, got "
                        f"{type(storyboard).__name__}")
    if not isinstance(animation, StoryboardAnimation):
        raise TypeError(f"animation must be the StoryboardAnimation of animate_storyboard, got "
                        f"{type(animation).__name__}")
    n = len(storyboard)
    if len(animation.segments) != n or len(animation.placements) != n:
        raise ValueError(f"the animation has {len(animation.segments)} clips and "
                         f"{len(animation.placements)} placements but the storyboard {n} "
                         f"frames; animate this storyboard again (animate_storyboard)")


def frame_camera(storyboard, i):
    """The camera of storyboard frame ``i``'s view: the frame's own; else, if it has 2D
    conditions, the storyboard's (the one :func:`~physlab.motion.generate` used); else its
    sketch's; else the storyboard's; else :data:`DEFAULT_CAMERA`."""
    f = storyboard.frames[i]
    if f.camera is not None:
        return f.camera
    if f.has_2d and storyboard.camera is not None:
        return storyboard.camera
    if f.sketch is not None:
        return f.sketch.camera
    return storyboard.camera or DEFAULT_CAMERA


def _frames_of(animation, i):
    start = 0 if i == 0 else animation.segments[i - 1].stop
    return range(start, animation.segments[i].stop)


def _chains(points):
    """The 5 kinematic chains of a (22, 2) pose as polylines."""
    return [np.asarray(points)[list(c)] for c in KINEMATIC_CHAINS]


def frame_view(storyboard, animation, i):
    """The :class:`FrameView` of storyboard frame ``i`` (module docstring).

    Parameters
    ----------
    storyboard : :class:`~physlab.motion.storyboard.Storyboard`.
    animation : its :class:`~physlab.motion.storyboard.StoryboardAnimation`.
    i : int, frame index (negative counts from the end).
    """
    _check_pair(storyboard, animation)
    n = len(storyboard)
    if not -n <= i < n:
        raise IndexError(f"frame {i} out of range for a storyboard of {n} frames")
    i %= n
    f = storyboard.frames[i]
    cam = frame_camera(storyboard, i)
    frames = _frames_of(animation, i)
    clip_len = len(range(*animation.segments[i].indices(len(animation.joints))))
    key_frame = {"first": 0, "last": clip_len - 1}[f.keypose_at]
    origin = ppu = canvas = None
    pose, traj = [], []
    if f.sketch is not None:
        sk = f.sketch
        if sk.joints is None and any(s.kind == "pose" for s in sk.strokes):
            sk = copy.deepcopy(sk)       # snap as Sketch.conditions did, not in the caller's
            sk.keypose()
        origin, ppu = sk.pixel_frame(*sk.trajectories_px())
        kind, y_down, units, canvas = "sketch", True, "px", tuple(sk.size)
        pose = [s.points for s in sk.strokes if s.kind == "pose"]
        if not pose and sk.joints is not None:
            pose = _chains(sk.joints)
        traj = [s.points for s in sk.strokes if s.kind == "trajectory"]
        if sk.joints is None:
            key_frame = None
    elif f.keypose_2d is not None or f.keypose_3d is not None or f.trajectories_2d \
            or f.trajectories_3d:
        kind, y_down, units = "conditions", False, "image units"
        if f.keypose_2d is not None:
            pose = _chains(f.keypose_2d)
        elif f.keypose_3d is not None:
            pose = _chains(cam.project(f.keypose_3d))
        else:
            key_frame = None
        traj = [np.asarray(v) for v in (f.trajectories_2d or {}).values()]
        traj += [cam.project(v) for v in (f.trajectories_3d or {}).values()]
    else:
        kind, y_down, units, key_frame = "text", False, "image units", None
    view = FrameView(kind, f.action, cam, y_down, units, canvas, pose, traj, key_frame,
                     frames, np.empty((0, 22, 2)), (0.0, 1.0, 0.0, 1.0), origin, ppu)
    motion = view.project(animation.local(i))                             # (n, 22, 2)
    every = view.project(animation.local(i, animation.joints[frames.start:frames.stop]))
    pts = [every.reshape(-1, 2)] + pose + traj
    if canvas is not None:
        pts.append(np.array([[0.0, 0.0], canvas]))
    pts = np.concatenate(pts)
    lo, hi = pts.min(0), pts.max(0)
    pad = 0.04 * max(hi - lo) + 1e-9
    lo, hi = lo - pad, hi + pad
    w, h = hi - lo
    if w < _MIN_ASPECT * h:              # a standing figure alone: widen to a card shape
        lo[0], hi[0] = 0.5 * (lo[0] + hi[0]) - 0.5 * _MIN_ASPECT * h, \
            0.5 * (lo[0] + hi[0]) + 0.5 * _MIN_ASPECT * h
    bounds = (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))
    return FrameView(kind, f.action, cam, y_down, units, canvas, pose, traj, key_frame,
                     frames, motion, bounds, origin, ppu)


# ----------------------------------------------------------------------------- contact sheet


def _frame_color(i):
    return FRAME_COLORS[i % len(FRAME_COLORS)]


def _check_every(every):
    if isinstance(every, bool) or not isinstance(every, (int, np.integer)) or every < 1:
        raise ValueError(f"every must be an integer >= 1 (draw a figure every so many frames), "
                         f"got {every!r}")
    return int(every)


def _strobe_indices(n, every):
    idx = list(range(0, n, every))
    if idx[-1] != n - 1:
        idx.append(n - 1)
    return idx


def _set_view_limits(ax, view):
    x0, x1, y0, y1 = view.bounds
    ax.set_xlim(x0, x1)
    ax.set_ylim((y1, y0) if view.y_down else (y0, y1))
    ax.set_aspect("equal")
    ax.tick_params(labelsize=7)
    ax.set_xlabel(f"x ({view.units})" if view.y_down else "u (image units)", fontsize=8)
    ax.set_ylabel(f"y ({view.units}, down)" if view.y_down else "v (image units, up)",
                  fontsize=8)


def _draw_drawing(ax, view, faint=False):
    from matplotlib.collections import LineCollection

    if view.canvas is not None:
        from matplotlib.patches import Rectangle

        ax.add_patch(Rectangle((0, 0), *view.canvas, fill=False, ec="0.8", lw=0.8, ls="--"))
    for kind, lines in (("pose", view.pose), ("trajectory", view.trajectory)):
        if lines:
            color = COLORS[("sketch_faint" if kind == "pose" else "trajectory_faint")
                           if faint else kind]
            ax.add_collection(LineCollection(lines, colors=color, linewidths=1.0 if faint
                                             else 1.8, capstyle="round", zorder=1))


def _draw_sketch_panel(ax, view, i, n):
    ax.set_title(f"{i + 1}/{n}  " + "\n".join(textwrap.wrap(view.action, 30)), fontsize=9,
                 color=_frame_color(i), fontweight="bold")
    _set_view_limits(ax, view)
    if view.kind == "text":
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_xlabel("text only: no sketch or conditions", fontsize=8)
        ax.set_ylabel("")
        ax.text(0.5, 0.5, "\u201c" + "\n".join(textwrap.wrap(view.action, 22)) + "\u201d",
                transform=ax.transAxes, ha="center", va="center", fontsize=10, style="italic",
                color="0.25")
        ax.set_facecolor("#f7f7f2")
        return
    _draw_drawing(ax, view)
    what = (f"sketch {view.canvas[0]}\u00d7{view.canvas[1]} px" if view.kind == "sketch"
            else "conditions (no sketch)")
    ax.text(0.02, 0.02, what, transform=ax.transAxes, fontsize=7, color="0.4", va="bottom")


def _draw_motion_panel(ax, view, every, i):
    from matplotlib.collections import LineCollection

    _set_view_limits(ax, view)
    if view.kind != "text":
        _draw_drawing(ax, view, faint=True)
    m = view.motion
    idx = _strobe_indices(len(m), every)
    alphas = np.linspace(0.35, 1.0, len(idx))
    for a, t in zip(alphas, idx):
        lw = 2.2 if t == view.key_frame else 1.1
        ax.add_collection(LineCollection(m[t][_BONES], colors=COLORS["motion"], alpha=a,
                                         linewidths=lw, capstyle="round", zorder=2))
    ax.plot(*m[:, 0].T, color=COLORS["motion"], lw=0.8, ls=":", zorder=2)
    cam = view.camera
    ax.set_title(f"result, clip {i + 1} (pitch {cam.pitch:g}\u00b0, yaw {cam.yaw:g}\u00b0)",
                 fontsize=8)


def _frame_labels(animation):
    """(N,) int: storyboard frame of each animation frame, -1 in a transition."""
    lab = np.full(len(animation.joints), -1)
    for i, s in enumerate(animation.segments):
        lab[s] = i
    return lab


def _draw_world_panel(ax, animation, every, axes, labels, title):
    """Stick figures every ``every`` frames and the pelvis path, world axes ``axes`` = (h, v)
    indices into (x, y, z)."""
    from matplotlib.collections import LineCollection

    x = animation.joints
    h, v = axes
    colors = [COLORS["transition"] if k < 0 else _frame_color(k) for k in labels]
    idx = _strobe_indices(len(x), every)
    segs = x[idx][:, _BONES][..., [h, v]]                                   # (F, 21, 2, 2)
    ax.add_collection(LineCollection(segs.reshape(-1, 2, 2),
                                     colors=np.repeat([colors[t] for t in idx], len(_BONES),
                                                      axis=0), linewidths=0.9))
    p = x[:, 0][:, [h, v]]
    ax.add_collection(LineCollection(np.stack([p[:-1], p[1:]], axis=1), colors=colors[1:],
                                     linewidths=2.0))
    ax.plot(*p[0], "o", ms=4, color="k")
    names = "xyz"
    ax.update_datalim(np.concatenate([segs.reshape(-1, 2), p]))
    ax.margins(0.04)
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.set_xlabel(f"{names[h]} (m)", fontsize=8)
    ax.set_ylabel(f"{names[v]} (m)", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)


def storyboard_contact_sheet(storyboard, animation, every=10, path=None):
    """One figure to compare a storyboard with its animation.

    Top row: each storyboard frame as drawn (:func:`frame_view`: sketch strokes in canvas
    pixels, y down; or its conditions in normalised units; or a text card), titled with its
    action in the frame's colour. Middle row: that frame's clip projected into the same view
    (blue stick figures every ``every`` frames, fainter earlier, the keypose frame thicker;
    dotted pelvis path) over a faint copy of the drawing. Bottom row: the whole animation
    (metres) from above (z–x, the floor seen from +y) and from the side (z–y, seen from
    −x), stick figures every ``every`` frames and the pelvis path coloured per storyboard
    frame (:data:`FRAME_COLORS`), transitions grey.

    Parameters
    ----------
    storyboard : :class:`~physlab.motion.storyboard.Storyboard`.
    animation : its :class:`~physlab.motion.storyboard.StoryboardAnimation`.
    every : int >= 1, frames between the drawn figures.
    path : None or a ``.png`` path, written atomically (dpi 100).

    Returns
    -------
    :class:`matplotlib.figure.Figure` with ``2 n + 2`` axes (10.2 × 6.8 inches for 3
    frames, 3.4 inches per frame, at most 17).
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    _check_pair(storyboard, animation)
    every = _check_every(every)
    n = len(storyboard)
    views = [frame_view(storyboard, animation, i) for i in range(n)]
    fig = Figure(figsize=(min(max(8.0, 3.4 * n), 17.0), 6.8), dpi=100, layout="constrained")
    gs = fig.add_gridspec(3, 1, height_ratios=[1.0, 1.0, 0.8])
    top = gs[0:2].subgridspec(2, n)
    for i, view in enumerate(views):
        _draw_sketch_panel(fig.add_subplot(top[0, i]), view, i, n)
        _draw_motion_panel(fig.add_subplot(top[1, i]), view, every, i)
    bottom = gs[2].subgridspec(1, 2)
    labels = _frame_labels(animation)
    _draw_world_panel(fig.add_subplot(bottom[0]), animation, every, (2, 0), labels,
                      "whole animation from above (+y): pelvis path on the floor")
    _draw_world_panel(fig.add_subplot(bottom[1]), animation, every, (2, 1), labels,
                      "whole animation from the side (seen from \u2212x)")
    handles = [Line2D([], [], color=_frame_color(i), lw=2,
                      label=f"{i + 1} {textwrap.shorten(v.action, 28, placeholder='…')}")
               for i, v in enumerate(views)]
    handles.append(Line2D([], [], color=COLORS["transition"], lw=2, label="transition"))
    fig.legend(handles=handles, loc="outside lower center", ncols=min(n + 1, 5), fontsize=8,
               frameon=False)
    title = storyboard.title or "storyboard"
    fig.suptitle(f"{title} \u2014 {len(animation.joints)} frames, "
                 f"{len(animation.joints) / 20:.1f} s at 20 fps", fontsize=10)
    if path is not None:
        atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=100), ".png")
    return fig


# ----------------------------------------------------------------------------- overlay frames


def _check_size(size):
    try:
        W, H = (int(v) for v in size)
    except (TypeError, ValueError):
        raise ValueError(f"size must be (width, height) in pixels, got {size!r}") from None
    if W < 64 or H < 64:
        raise ValueError(f"size must be at least (64, 64) pixels, got {size!r}")
    return W, H


def _fit(view, W, H, top, margin):
    """Affine map view coordinates -> output pixels (y down) that fits ``view.bounds`` into
    the ``W × (H - top)`` area below the header: returns ``f(points (..., 2)) -> (..., 2)``."""
    x0, x1, y0, y1 = view.bounds
    s = min((W - 2 * margin) / (x1 - x0), (H - top - 2 * margin) / (y1 - y0))
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    ox, oy = 0.5 * W, top + 0.5 * (H - top)
    sy = s if view.y_down else -s

    def f(p):
        p = np.asarray(p, dtype=float)
        return np.stack([ox + s * (p[..., 0] - cx), oy + sy * (p[..., 1] - cy)], axis=-1)
    return f


def _font(px):
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=px)
    except TypeError:                          # Pillow < 10.1: fixed-size bitmap font
        return ImageFont.load_default()


def _fit_text(draw, text, font, width):
    if draw.textlength(text, font=font) <= width:
        return text
    while text and draw.textlength(text + "…", font=font) > width:
        text = text[:-1]
    return text + "…"


def sketch_overlay_frames(storyboard, animation, size=(320, 320)):
    """The storyboard drawings with the animation over them, one image per animation frame.

    Frame ``k`` shows storyboard frame ``i = animation.frame_at(k)`` as in the contact sheet
    (:func:`frame_view`: its sketch strokes, its conditions, or nothing but the text), the
    current pose moved into clip ``i``'s canonical frame and projected into that view as a
    blue stick figure (:data:`COLORS`), and a header with ``i + 1/n``, the action and the
    time. Each view is scaled to fit its canvas, drawing and all of its frames (transition
    included), so the figure never leaves the picture. Drawn with PIL at twice the size and
    box-filtered down (antialiasing); ~3 ms per frame at 320 × 320.

    Parameters
    ----------
    storyboard, animation : as in :func:`storyboard_contact_sheet`.
    size : ``(width, height)`` pixels, at least (64, 64).

    Returns
    -------
    ``(N, H, W, 3)`` uint8, ``N = len(animation.joints)``.
    """
    from PIL import Image, ImageDraw

    _check_pair(storyboard, animation)
    W, H = _check_size(size)
    ss = 2                                                   # supersampling factor
    Ws, Hs = ss * W, ss * H
    header = ss * max(16, H // 14)
    font = _font(int(0.62 * header))
    n, x = len(storyboard), animation.joints
    blue = _rgb255(COLORS["motion"])
    lw = max(2, round(ss * W / 160))
    out = np.empty((len(x), H, W, 3), np.uint8)
    for i in range(n):
        view = frame_view(storyboard, animation, i)
        fit = _fit(view, Ws, Hs, header, margin=0.04 * Ws)
        bg = Image.new("RGB", (Ws, Hs), "white")
        d = ImageDraw.Draw(bg)
        if view.canvas is not None:
            c = fit(np.array([[0.0, 0.0], view.canvas]))
            d.rectangle([*c.min(0), *c.max(0)], outline=(215, 215, 215), width=ss)
        for kind, lines in (("pose", view.pose), ("trajectory", view.trajectory)):
            for line in lines:
                d.line([tuple(p) for p in fit(line)], fill=_rgb255(COLORS[kind]), width=lw,
                       joint="curve")
        if view.kind == "text":
            d.text((ss * 4, Hs - ss * 4), "text only: no sketch", fill=(150, 150, 150),
                   font=font, anchor="lb")
        d.rectangle([0, 0, Ws, header], fill=(240, 240, 236))
        label = f"{i + 1}/{n} {view.action}"
        for k in view.frames:
            img = bg.copy()
            dk = ImageDraw.Draw(img)
            trans = k not in range(*animation.segments[i].indices(len(x)))
            right = ("transition " if trans else "") + f"{k / 20:.2f} s"
            rw = dk.textlength(right, font=font)
            dk.text((ss * 4, header / 2), _fit_text(dk, label, font, Ws - rw - ss * 14),
                    fill=_rgb255(_frame_color(i)) if not trans else (110, 110, 110),
                    font=font, anchor="lm")
            dk.text((Ws - ss * 4, header / 2), right, fill=(90, 90, 90), font=font,
                    anchor="rm")
            p = fit(view.project(animation.local(i, x[k:k + 1])[0]))       # (22, 2) px
            for a, b in _BONES:
                dk.line([tuple(p[a]), tuple(p[b])], fill=blue, width=lw)
            r = 1.6 * lw
            dk.ellipse([p[0, 0] - r, p[0, 1] - r, p[0, 0] + r, p[0, 1] + r], fill=blue)
            hr = 2.2 * lw
            dk.ellipse([p[15, 0] - hr, p[15, 1] - hr, p[15, 0] + hr, p[15, 1] + hr],
                       outline=blue, width=max(1, lw // 2))
            out[k] = np.asarray(img.reduce(ss))
    return out


def overlay_pixel(storyboard, animation, k, joint=0, size=(320, 320)):
    """Where joint ``joint`` of animation frame ``k`` lands in
    :func:`sketch_overlay_frames` ``(...)[k]``: ``(2,)`` float pixels ``(x, y)``."""
    W, H = _check_size(size)
    ss = 2
    header = ss * max(16, H // 14)
    i = animation.frame_at(k)
    view = frame_view(storyboard, animation, i)
    fit = _fit(view, ss * W, ss * H, header, margin=0.04 * ss * W)
    p = fit(view.project(animation.local(i, animation.joints[k:k + 1])[0, joint]))
    return (p + 0.5) / ss - 0.5                 # supersampled pixel centres -> output


# ----------------------------------------------------------------------------- files


def _check_formats(formats):
    if isinstance(formats, str):
        formats = (formats,)
    formats = tuple(formats)
    bad = [f for f in formats if f not in EXPORT_FILES]
    if bad:
        raise ValueError(f"unknown export format(s) {bad}; choose from {list(EXPORT_FORMATS)}")
    return tuple(dict.fromkeys(formats))


#: Frame rate of a storyboard animation (the generator's clips are 20 fps).
ANIMATION_FPS = 20.0


def resample_frames(joints, fps_in, fps_out):
    """``joints`` (T, ...) sampled at ``fps_in`` resampled to ``fps_out`` over the same
    duration: returns ``(resampled (T', ...), nearest (T',) int)`` with ``T' = round((T − 1)
    fps_out / fps_in) + 1``, positions linear in time between the two nearest input frames,
    ``nearest`` the index of the nearest input frame (for images). The same rate returns the
    input unchanged."""
    x = np.asarray(joints, dtype=float)
    if fps_out == fps_in:
        return x, np.arange(len(x))
    n = int(round((len(x) - 1) * fps_out / fps_in)) + 1
    t = np.linspace(0.0, len(x) - 1.0, n)                 # output times in input frames
    i0 = np.minimum(np.floor(t).astype(int), len(x) - 2) if len(x) > 1 else np.zeros(n, int)
    w = (t - i0).reshape((-1,) + (1,) * (x.ndim - 1))
    i1 = np.minimum(i0 + 1, len(x) - 1)
    return (1 - w) * x[i0] + w * x[i1], np.rint(t).astype(int)


def export_storyboard(storyboard, animation, folder,
                      formats=("bvh", "gif", "mp4", "sketch_gif", "json", "png"), fps=20,
                      backend="matplotlib", progress=False):
    """Write a storyboard and its animation into ``folder`` (created), one file per format
    (names :data:`EXPORT_FILES`), each atomically (a failed write keeps the previous file).

    * ``"bvh"`` — the whole animation as BVH (:func:`~physlab.motion.export.joints_to_bvh`;
      a generated clip's bones stretch a little, so the file holds the closest rigid skeleton
      and the exporter warns with the largest joint error);
    * ``"gif"`` / ``"mp4"`` — the capsule human (:func:`~physlab.viz.view3d.render_motion`
      with ``backend``, rendered once for both);
    * ``"sketch_gif"`` — :func:`sketch_overlay_frames` as a GIF;
    * ``"json"`` — :meth:`~physlab.motion.storyboard.Storyboard.save`;
    * ``"png"`` — :func:`storyboard_contact_sheet`.

    Parameters
    ----------
    storyboard, animation : as in :func:`storyboard_contact_sheet`.
    folder : str or Path.
    formats : iterable of names from :data:`EXPORT_FORMATS` (ValueError naming unknown ones).
    fps : float > 0, frame rate of the BVH and the videos. The animation is 20 fps; at
        another rate its joints are resampled in time (linearly; :func:`resample_frames`) and
        the overlay GIF shows the nearest 20-fps frame, so every file lasts as long as the
        animation.
    backend : ``"matplotlib"`` | ``"pyvista"`` | ``"auto"`` for the capsule human.
    progress : tqdm bar over the files (and the render).

    Returns
    -------
    dict format -> :class:`~pathlib.Path` of the written file, in ``formats`` order.
    """
    formats = _check_formats(formats)
    _check_pair(storyboard, animation)
    if isinstance(fps, bool) or not isinstance(fps, (int, float, np.integer, np.floating)) \
            or not np.isfinite(fps) or fps <= 0:
        raise ValueError(f"fps must be a number > 0 (the animation is 20 fps), got {fps!r}")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = {f: folder / EXPORT_FILES[f] for f in formats}
    steps = formats
    if progress:
        from tqdm.auto import tqdm

        steps = tqdm(formats, desc="export", leave=False)
    rendered = None
    joints, nearest = resample_frames(animation.joints, ANIMATION_FPS, fps)
    out = {}
    for f in steps:
        p = paths[f]
        if f == "bvh":
            from physlab.motion.export import joints_to_bvh

            out[f] = joints_to_bvh(joints, p, fps=fps)
        elif f in ("gif", "mp4"):
            from physlab.render import frames_to_gif, frames_to_mp4
            from physlab.viz.view3d import render_motion

            if rendered is None:
                rendered = np.asarray(render_motion(joints, backend=backend,
                                                    progress=progress))
            out[f] = (frames_to_gif(rendered, p, fps=fps) if f == "gif"
                      else frames_to_mp4(rendered, p, fps=fps))
        elif f == "sketch_gif":
            from physlab.render import frames_to_gif

            frames = sketch_overlay_frames(storyboard, animation)
            out[f] = frames_to_gif([frames[k] for k in nearest], p, fps=fps)
        elif f == "json":
            out[f] = Path(storyboard.save(p))
        else:                                                            # "png"
            storyboard_contact_sheet(storyboard, animation, path=p)
            out[f] = p
    return {f: out[f] for f in formats}


def check_bvh(path, n_frames=None, fps=20):
    """Read a BVH written by :func:`export_storyboard` (or
    :func:`~physlab.motion.export.joints_to_bvh`) back and check it.

    It must hold exactly the 22 joints of :data:`~physlab.motion.skeleton.JOINT_NAMES` with
    the parents of :data:`~physlab.motion.skeleton.PARENTS`, an ``End Site`` (read as
    ``"<joint>_End"``) on each leaf of :data:`~physlab.motion.export.END_SITES` and nowhere
    else, position + rotation channels on the pelvis and rotation channels on the others;
    ``n_frames`` frames (if given) and a frame time of ``1 / fps``. ValueError naming the file
    and what differs otherwise.

    Returns
    -------
    dict: ``names`` (22 joint names in the file's hierarchy order), ``parents`` ((22,) int,
    index into ``names``, -1 for the root), ``end_sites`` (names), ``n_frames``,
    ``frame_time`` (s), ``fps``, ``joints`` ((T, 22, 3) float, m: forward kinematics of the
    file in :data:`~physlab.motion.skeleton.JOINT_NAMES` order).
    """
    from physlab.motion.bvh import read_bvh
    from physlab.motion.export import END_SITES

    path = Path(path)
    m = read_bvh(path)

    def fail(msg):
        raise ValueError(f"{path}: {msg}; expected the 22-joint HumanML3D skeleton of "
                         f"physlab.motion.skeleton as written by joints_to_bvh")

    ends = {f"{JOINT_NAMES[j]}_End": JOINT_NAMES[j] for j in END_SITES}
    body = [k for k, nm in enumerate(m.names) if nm not in ends]
    names = [m.names[k] for k in body]
    missing = [nm for nm in JOINT_NAMES if nm not in names]
    extra = [nm for nm in names if nm not in JOINT_NAMES]
    if missing or extra or len(names) != len(set(names)):
        fail(f"joints missing {missing}, unexpected {extra}"
             + ("" if len(names) == len(set(names)) else ", some named twice"))
    for k in body:
        nm, p = m.names[k], m.parents[k]
        want = PARENTS[JOINT_NAMES.index(nm)]
        got = None if p < 0 else m.names[p]
        if got != (None if want < 0 else JOINT_NAMES[want]):
            fail(f"joint {nm!r} has parent {got!r}, not "
                 f"{None if want < 0 else JOINT_NAMES[want]!r}")
        rot = [c for c in m.channels[k] if c.endswith("rotation")]
        pos = [c for c in m.channels[k] if c.endswith("position")]
        if len(rot) != 3 or len(pos) != (3 if want < 0 else 0):
            fail(f"joint {nm!r} has channels {m.channels[k]}; the pelvis needs 3 position and "
                 f"3 rotation channels, the others 3 rotation channels")
    found_ends = [nm for nm in m.names if nm in ends]
    for nm in found_ends:
        k = m.names.index(nm)
        if m.parents[k] < 0 or m.names[m.parents[k]] != ends[nm]:
            fail(f"end site {nm!r} is not under {ends[nm]!r}")
    if sorted(found_ends) != sorted(ends):
        fail(f"end sites {sorted(found_ends)}, expected {sorted(ends)}")
    if n_frames is not None and m.n_frames != n_frames:
        raise ValueError(f"{path}: {m.n_frames} frames, expected {n_frames}")
    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps!r}")
    if not np.isclose(m.frame_time, 1.0 / fps, rtol=1e-6, atol=0.0):
        raise ValueError(f"{path}: Frame Time {m.frame_time:g} s is not 1/{fps:g} = "
                         f"{1.0 / fps:g} s")
    index = {nm: k for k, nm in enumerate(names)}
    parents = np.array([-1 if m.parents[k] < 0 else index[m.names[m.parents[k]]]
                        for k in body])
    joints = m.joint_positions()[:, [m.joint_index(nm) for nm in JOINT_NAMES]]
    return {"names": names, "parents": parents, "end_sites": found_ends,
            "n_frames": m.n_frames, "frame_time": m.frame_time, "fps": 1.0 / m.frame_time,
            "joints": joints}
