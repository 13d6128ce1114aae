"""A storyboard editor for JupyterLab: a strip of frames, each drawn in the sketch canvas (or
just described by its action), generated into one animation and exported (Sketch2Anim
Secs. 3 and 6, Fig. 1; lesson 10's :class:`~physlab.viz.sketch_canvas.SketchCanvas` for one
frame).

The editor holds one *draft* per storyboard frame: its action text, ``keypose_at``, the sketch
shown in the canvas (a new empty sketch for a frame without one) and the frame it started
from. A draft becomes a :class:`~physlab.motion.storyboard.StoryboardFrame` when the
storyboard is needed (:attr:`StoryboardEditor.storyboard`: Generate, Save, thumbnails): an
untouched draft gives back its frame unchanged; a drawn sketch gives
:meth:`~physlab.motion.storyboard.StoryboardFrame.from_sketch` (its camera becomes the
frame's, ``keypose_at`` comes from the trajectory strokes when there are any, from the
dropdown otherwise; 3D conditions of the original frame are kept); an empty sketch keeps the
original frame's conditions without the sketch (a text-only frame keeps only its action).

Layout, top to bottom:

* title, storyboard file, **Save** / **Load** (JSON, :meth:`~physlab.motion.storyboard.
  Storyboard.save`);
* the strip: one thumbnail per frame (its sketch, its conditions, or an action card;
  :func:`frame_thumbnail`) over a button that selects it; **Add frame** (after the selected
  one), **Delete**, **◀ Move**, **Move ▶**;
* the selected frame: its action, ``keypose_at`` and one :class:`~physlab.viz.sketch_canvas.
  SketchCanvas` (its own Generate and result image are hidden: the editor generates the whole
  storyboard);
* the storyboard: camera pitch / yaw (used by frames without a camera of their own),
  transition length in frames (0 = a plain cut, blending ``"concat"``), blending method
  (:data:`~physlab.motion.blend.BLEND_METHODS`), seed; **Generate** with a progress bar over
  the frames and junctions (the tqdm bar of :func:`~physlab.motion.storyboard.
  animate_storyboard`, shown inside the widget);
* the status line (errors name the frame, numbered from 1 as in the strip);
* the preview: one looping GIF of the capsule human (:func:`~physlab.viz.view3d.
  render_motion`) next to the storyboard frame that plays with the pose over it
  (:func:`~physlab.viz.storyboard_view.sketch_overlay_frames`, whose header names the frame),
  a timeline of the clips and transitions, **Export** (the folder of
  :func:`~physlab.viz.storyboard_view.export_storyboard`) and the list of written files.

Generation runs synchronously in the button's callback (a few seconds with fast
``generate_options`` such as ``{"steps": 20, "guidance_final": 0}``).
"""
from __future__ import annotations

import copy
import html
import json
import re
import textwrap
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from physlab.motion.blend import BLEND_METHODS, TRANSITION
from physlab.motion.camera import Camera
from physlab.motion.conditions import KEYPOSE_AT, N_FRAMES
from physlab.motion.sketch import Sketch
from physlab.motion.skeleton import KINEMATIC_CHAINS
from physlab.motion.storyboard import Storyboard, StoryboardFrame
from physlab.viz.canvas_widget import CanvasWidget, png_bytes
from physlab.viz.storyboard_view import (_BONES, DEFAULT_CAMERA, EXPORT_FORMATS, _fit_text,
                                         _font)

__all__ = ["StoryboardEditor", "frame_thumbnail", "preview_frames", "THUMB_SIZE",
           "PREVIEW_SIZE", "PREVIEW_EVERY", "NEW_ACTION"]

#: Thumbnail size (width, height) px in the strip.
THUMB_SIZE = (128, 100)
#: Size (width, height) px of each half of the preview (capsule human | sketch overlay).
PREVIEW_SIZE = (320, 320)
#: The preview shows every so many animation frames (at ``20 / PREVIEW_EVERY`` fps, so it
#: plays in real time); exports keep every frame.
PREVIEW_EVERY = 2
#: Action text of a new frame.
NEW_ACTION = "a person walks"
#: Canvas size (width, height) px of a new sketch when the storyboard has no sketch to copy
#: the size of.
NEW_SKETCH_SIZE = (480, 400)

_COLORS = {"pose": (0, 0, 0), "trajectory": (220, 0, 0), "joints": (31, 119, 180),
           "card": (247, 247, 242), "header": (236, 236, 232), "border": (190, 190, 190),
           "selected": (31, 119, 180), "text": (70, 70, 70)}
#: Warnings the status line does not repeat (library housekeeping, not about the result).
_QUIET = (DeprecationWarning, PendingDeprecationWarning, FutureWarning, ImportWarning,
          ResourceWarning)


# ----------------------------------------------------------------------------- thumbnails


def _drawing(sketch, frame, camera):
    """What a thumbnail draws: ``(kind, pose polylines, trajectory polylines, canvas size or
    None, y_down)``; polylines ``(n, 2)`` in canvas pixels (sketch) or image units (v up)."""
    if sketch is not None and (sketch.strokes or sketch.joints is not None):
        pose = [s.points for s in sketch.strokes if s.kind == "pose"]
        if not pose and sketch.joints is not None:     # joints placed without strokes
            pose = [sketch.joints[list(c)] for c in KINEMATIC_CHAINS]
        traj = [s.points for s in sketch.strokes if s.kind == "trajectory"]
        return "sketch", pose, traj, tuple(sketch.size), True
    if frame is None:
        return "text", [], [], None, False
    cam = frame.camera or camera or DEFAULT_CAMERA
    pose = []
    if frame.keypose_2d is not None:
        pose = [frame.keypose_2d[list(c)] for c in KINEMATIC_CHAINS]
    elif frame.keypose_3d is not None:
        uv = cam.project(frame.keypose_3d)
        pose = [uv[list(c)] for c in KINEMATIC_CHAINS]
    traj = [np.asarray(v) for v in (frame.trajectories_2d or {}).values()]
    traj += [cam.project(v) for v in (frame.trajectories_3d or {}).values()]
    return ("conditions" if pose or traj else "text"), pose, traj, None, False


def _thumbnail(action, label, sketch=None, frame=None, camera=None, size=THUMB_SIZE,
               selected=False, note=""):
    """(H, W, 3) uint8 thumbnail; see :func:`frame_thumbnail`."""
    from PIL import Image, ImageDraw

    W, H = (int(v) for v in size)
    ss = 2                                                     # supersampled, then reduced
    Ws, Hs, head = ss * W, ss * H, ss * 15
    kind, pose, traj, canvas, y_down = _drawing(sketch, frame, camera)
    img = Image.new("RGB", (Ws, Hs), _COLORS["card"] if kind == "text" else (255, 255, 255))
    d = ImageDraw.Draw(img)
    font, small = _font(ss * 10), _font(ss * 9)
    if kind == "text":
        lines = textwrap.wrap(f"“{action}”", 18)[:4] or ["(no action)"]
        y = head + (Hs - head) / 2 - 0.5 * ss * 12 * (len(lines) - 1)
        for line in lines:
            d.text((Ws / 2, y), line, fill=_COLORS["text"], font=font, anchor="mm")
            y += ss * 12
    else:
        pts = np.concatenate(pose + traj + ([np.array([[0.0, 0.0], canvas])] if canvas
                                           else []))
        lo, hi = pts.min(0), pts.max(0)
        m = 4 * ss
        s = min((Ws - 2 * m) / max(hi[0] - lo[0], 1e-9),
                (Hs - head - 2 * m) / max(hi[1] - lo[1], 1e-9))
        c, o = 0.5 * (lo + hi), np.array([Ws / 2, head + (Hs - head) / 2])
        flip = np.array([1.0, 1.0 if y_down else -1.0])

        def fit(p):
            return [tuple(q) for q in o + s * flip * (np.asarray(p, float) - c)]

        if canvas:
            d.rectangle([*fit([[0, 0]])[0], *fit([canvas])[0]], outline=(225, 225, 225),
                        width=ss)
        for k, lines in (("pose", pose), ("trajectory", traj)):
            for line in lines:
                if len(line) > 1:
                    d.line(fit(line), fill=_COLORS[k], width=ss * 2, joint="curve")
        if kind == "sketch" and sketch.joints is not None and any(
                st.kind == "pose" for st in sketch.strokes):
            for a, b in _BONES:
                d.line(fit(sketch.joints[[a, b]]), fill=_COLORS["joints"], width=ss)
    d.rectangle([0, 0, Ws, head], fill=_COLORS["header"])
    tag = note or {"sketch": "sketch", "conditions": "conditions", "text": "text"}[kind]
    tw = d.textlength(tag, font=small)
    d.text((3 * ss, head / 2), _fit_text(d, label, font, Ws - tw - 10 * ss), fill=(0, 0, 0),
           font=font, anchor="lm")
    d.text((Ws - 3 * ss, head / 2), tag, fill=(110, 110, 110), font=small, anchor="rm")
    color, width = ((_COLORS["selected"], 3 * ss) if selected else (_COLORS["border"], ss))
    d.rectangle([0, 0, Ws - 1, Hs - 1], outline=color, width=width)
    return np.asarray(img.reduce(ss))


def frame_thumbnail(frame, label="", size=THUMB_SIZE, selected=False, camera=None):
    """A small picture of a storyboard frame: its sketch strokes (pose black, trajectories
    red, snapped joints blue) in the canvas rectangle; else its keypose and trajectories
    (2D as drawn, 3D projected by the frame's camera, else ``camera``, else
    :data:`~physlab.viz.storyboard_view.DEFAULT_CAMERA`); else a card with its action. A
    header shows ``label`` and what is drawn; ``selected`` draws a thick blue border.

    Parameters
    ----------
    frame : :class:`~physlab.motion.storyboard.StoryboardFrame`.
    label : str, e.g. ``"2 a person bows"``.
    size : ``(width, height)`` px, at least (48, 40).
    camera : the storyboard's :class:`~physlab.motion.camera.Camera` or None.

    Returns
    -------
    ``(height, width, 3)`` uint8.
    """
    if not isinstance(frame, StoryboardFrame):
        raise TypeError(f"frame must be a StoryboardFrame, got {type(frame).__name__}")
    W, H = (int(v) for v in size)
    if W < 48 or H < 40:
        raise ValueError(f"size must be at least (48, 40) px, got {size!r}")
    return _thumbnail(frame.action, label, frame.sketch, frame, camera, (W, H), selected)


# ----------------------------------------------------------------------------- preview


def preview_frames(storyboard, animation, every=PREVIEW_EVERY, size=PREVIEW_SIZE,
                   backend="matplotlib"):
    """The preview of an animation: every ``every``-th frame of the capsule human
    (:func:`~physlab.viz.view3d.render_motion`) with, to its right, the same frame of
    :func:`~physlab.viz.storyboard_view.sketch_overlay_frames` (the storyboard frame that
    plays, named in its header, with the pose projected over its drawing).

    Returns
    -------
    ``(ceil(N / every), H, 2 W, 3)`` uint8, ``(W, H) = size``.
    """
    from physlab.viz.storyboard_view import sketch_overlay_frames
    from physlab.viz.view3d import render_motion

    if isinstance(every, bool) or not isinstance(every, (int, np.integer)) or every < 1:
        raise ValueError(f"every must be an integer >= 1, got {every!r}")
    W, H = (int(v) for v in size)
    idx = np.arange(0, len(animation.joints), int(every))
    human = np.asarray(render_motion(animation.joints[idx], size=(W, H), backend=backend))
    overlay = sketch_overlay_frames(storyboard, animation, size=(W, H))[idx]
    return np.concatenate([human[..., :3], overlay], axis=2)               # (n, H, 2W, 3)


def _gif_bytes(frames, fps):
    import imageio.v3 as iio

    return iio.imwrite("<bytes>", np.asarray(frames, np.uint8), extension=".gif",
                       duration=1000 / fps, loop=0)


def _timeline(animation, storyboard, fps=20):
    """HTML: which storyboard frame plays when."""
    parts = []
    for i, s in enumerate(animation.segments):
        if i > 0:
            t = animation.transitions[i - 1]
            if t.stop > t.start:
                parts.append(f'<span style="color:#888">blend {t.start / fps:.2f}–'
                             f'{t.stop / fps:.2f} s</span>')
        act = html.escape(textwrap.shorten(storyboard.frames[i].action, 32, placeholder="…"))
        parts.append(f"<b>{i + 1}</b> {act} {s.start / fps:.2f}–{s.stop / fps:.2f} s")
    return " · ".join(parts)


# ----------------------------------------------------------------------------- the widget


def _drawn(sketch):
    return bool(sketch.strokes) or sketch.joints is not None


def _state(sketch):
    return json.dumps(sketch.to_dict(), sort_keys=True)


@dataclass
class _Draft:
    """One frame being edited: the action, ``keypose_at``, the canvas's sketch, the frame it
    started from (None for a new one) and the state it had then (to tell an untouched draft)."""
    action: str
    keypose_at: str
    sketch: Sketch
    frame: StoryboardFrame | None = None
    start: tuple = field(default=())

    def __post_init__(self):
        self.start = self.signature()

    def signature(self):
        return (self.action, self.keypose_at, _state(self.sketch))


def _close(widget):
    """Close a widget and everything inside it (boxes' children, a MultiCanvas's layers)."""
    for child in list(getattr(widget, "children", ())) + list(getattr(widget, "_canvases", ())):
        _close(child)
    widget.close()


class StoryboardEditor(CanvasWidget):
    """The widget (``display(StoryboardEditor(...).widget)``; module docstring).

    Parameters
    ----------
    storyboard : None (one text-only frame), a :class:`~physlab.motion.storyboard.Storyboard`
        or a path to its JSON.
    generate_options : dict of further keywords of :func:`~physlab.motion.storyboard.
        animate_storyboard` (``steps``, ``guidance_final``, ``checkpoint``,
        ``blend_options`` ...).
    backend : capsule-human renderer of the preview and the export, ``"matplotlib"`` |
        ``"pyvista"`` | ``"auto"``.
    export_dir : folder that Export writes into (editable in the widget).

    Attributes
    ----------
    widget : the box to display. storyboard : the current :class:`~physlab.motion.storyboard.
    Storyboard` (built from the drafts; ValueError naming the frame if one is invalid, or if
    there is no frame). selected : index of the frame in the canvas, or None. canvas : its
    :class:`~physlab.viz.sketch_canvas.SketchCanvas`. animation : the last
    :class:`~physlab.motion.storyboard.StoryboardAnimation` or None; animated : the
    storyboard it was generated from. exported : ``{format: Path}`` of the last export;
    export_formats : what Export writes (default all of
    :data:`~physlab.viz.storyboard_view.EXPORT_FORMATS`).
    status : the status line (HTML).

    Controls (ipywidgets, public so code and tests can use them): ``title``, ``file``,
    ``save_button``, ``load_button``, ``frame_buttons`` (one per frame), ``add_button``,
    ``delete_button``, ``left_button``, ``right_button``, ``action``, ``keypose_at``,
    ``pitch``, ``yaw``, ``transition``, ``method``, ``seed``, ``generate_button``,
    ``progress`` (an Output holding the progress bar while working), ``preview`` (Image, GIF),
    ``timeline``, ``export_dir``, ``export_button``, ``files``.
    """

    shown_errors = (ValueError, TypeError, OSError, RuntimeError, IndexError)

    def __init__(self, storyboard=None, generate_options=None, backend="matplotlib",
                 export_dir="storyboard_export"):
        import ipywidgets as w

        if isinstance(storyboard, (str, Path)):
            storyboard = Storyboard.load(storyboard)
        if storyboard is not None and not isinstance(storyboard, Storyboard):
            raise TypeError(f"storyboard must be a Storyboard, a path to its JSON or None, got "
                            f"{type(storyboard).__name__}")
        if generate_options is not None and not isinstance(generate_options, dict):
            raise TypeError(f"generate_options must be a dict of keywords of "
                            f"animate_storyboard, got {type(generate_options).__name__}")
        taken = sorted(set(generate_options or {}) & {"transition", "seed", "method", "progress"})
        if taken:
            raise ValueError(f"generate_options must not set {taken}: the editor's controls set "
                             f"them (transition slider, seed, blending dropdown)")
        if backend not in ("matplotlib", "pyvista", "auto"):
            raise ValueError(f"backend must be 'matplotlib', 'pyvista' or 'auto', got "
                             f"{backend!r}")
        self.options = dict(generate_options or {})
        self.backend = backend
        self.drafts, self.selected, self.canvas = [], None, None
        self.animation = self.animated = None
        self.exported = {}
        self.export_formats = EXPORT_FORMATS
        self._links, self._slots = [], []
        wide = w.Layout(width="420px")

        small = w.Layout(width="90px")
        self.title = w.Text(description="title", layout=w.Layout(width="280px"))
        self.file = w.Text(value="storyboard.json", description="file",
                           layout=w.Layout(width="300px"))
        self.save_button = w.Button(description="Save", tooltip="write the storyboard JSON",
                                    layout=small)
        self.load_button = w.Button(description="Load", tooltip="read a storyboard JSON",
                                    layout=small)
        self.strip = w.HBox(layout=w.Layout(overflow="auto hidden", max_width="100%",
                                            padding="2px"))
        self.add_button = w.Button(description="Add frame",
                                   tooltip="a new text-only frame after the selected one")
        self.delete_button = w.Button(description="Delete",
                                      tooltip="delete the selected frame")
        self.left_button = w.Button(description="◀ Move", tooltip="move the frame earlier")
        self.right_button = w.Button(description="Move ▶", tooltip="move the frame later")
        self.frame_title = w.HTML()
        self.action = w.Text(description="action", layout=w.Layout(width="460px"),
                             continuous_update=False)
        self.keypose_at = w.Dropdown(options=list(KEYPOSE_AT), description="keypose at",
                                     layout=w.Layout(width="200px"),
                                     tooltip="the clip frame the keypose is at (trajectory "
                                             "strokes decide it when there are any)")
        self.frame_note = w.HTML()
        self.canvas_box = w.Box()
        self.pitch = w.FloatSlider(min=0, max=45, step=1, description="pitch°",
                                   continuous_update=False)
        self.yaw = w.FloatSlider(min=-90, max=90, step=1, description="yaw°",
                                 continuous_update=False)
        self.transition = w.IntSlider(value=TRANSITION, min=0, max=N_FRAMES - 2,
                                      description="transition",
                                      continuous_update=False,
                                      tooltip="frames between clips; 0 = a plain cut")
        self.method = w.Dropdown(options=list(BLEND_METHODS), value="inversion",
                                 description="blending", layout=w.Layout(width="260px"),
                                 tooltip="how adjacent clips are joined (Sketch2Anim: "
                                         "inversion)")
        self.seed = w.BoundedIntText(value=0, min=0, max=2**31 - 1, description="seed",
                                     layout=w.Layout(width="200px"))
        self.generate_button = w.Button(description="Generate", button_style="primary",
                                        tooltip="generate every frame and join "
                                                             "them")
        self.progress = w.Output(layout=w.Layout(width="520px", margin="0 0 0 12px"))
        self.readout = w.HTML()
        self.readout.add_class("physlab-readout")
        W, H = PREVIEW_SIZE
        self.preview = w.Image(format="gif", layout=w.Layout(
            display="none", width=f"{2 * W}px", height=f"{H}px", object_fit="contain"))
        self.preview.add_class("physlab-storyboard-preview")
        cell = f'<div style="width:{W}px;text-align:center;color:#555">'
        self.preview_caption = w.HTML(
            f'<div style="display:flex">{cell}the capsule human (3D)</div>{cell}the playing '
            f'frame, the pose projected in its view</div></div>',
            layout=w.Layout(display="none"))
        self.timeline = w.HTML()
        self.export_dir = w.Text(value=str(export_dir), description="folder", layout=wide)
        self.export_button = w.Button(description="Export",
                                      tooltip="BVH, GIF, MP4, overlay GIF, JSON, contact sheet")
        self.files = w.HTML()

        self._on_clicks(((self.save_button, self.save), (self.load_button, self.load),
                         (self.add_button, self.add_frame),
                         (self.delete_button, self.delete_frame),
                         (self.left_button, lambda: self.move(-1)),
                         (self.right_button, lambda: self.move(+1)),
                         (self.generate_button, self.generate),
                         (self.export_button, self.export)))
        self.action.observe(lambda _c: self._guard(self._edited), names="value")
        self.keypose_at.observe(lambda _c: self._guard(self._edited), names="value")
        for s in (self.pitch, self.yaw):      # thumbnails of 3D conditions use this camera
            s.observe(lambda _c: self._guard(self._refresh_strip), names="value")

        def heading(text):
            return w.HTML(f"<b>{text}</b>")

        storyboard_box = w.HBox([
            w.VBox([heading("storyboard camera"), self.pitch, self.yaw,
                    w.HTML('<span style="color:#666;font-size:90%">for frames without a '
                           'camera of their own</span>')],
                   layout=w.Layout(margin="0 24px 0 0")),
            w.VBox([heading("joining the clips"), self.transition, self.method, self.seed])],
            layout=w.Layout(flex_flow="row wrap", margin="8px 0 4px 0"))
        self.widget = w.VBox([
            w.HBox([self.title, self.file, self.save_button, self.load_button],
                   layout=w.Layout(flex_flow="row wrap")),
            self.strip,
            w.HBox([self.add_button, self.delete_button, self.left_button, self.right_button]),
            self.frame_title,
            w.HBox([self.action, self.keypose_at], layout=w.Layout(flex_flow="row wrap")),
            self.frame_note,
            self.canvas_box,
            storyboard_box,
            w.HBox([self.generate_button, self.progress], layout=w.Layout(align_items="center")),
            self.readout,
            self.preview_caption,
            self.preview,
            self.timeline,
            w.HBox([self.export_dir, self.export_button]),
            self.files])
        self.widget.add_class("physlab-storyboard-editor")
        self.set_storyboard(storyboard if storyboard is not None
                            else Storyboard([StoryboardFrame(NEW_ACTION)]))

    # ------------------------------------------------------------------ state
    @property
    def camera(self):
        """The storyboard camera of the sliders (scale and roll kept from the loaded one)."""
        c = self._camera0
        return Camera(c.scale, float(self.pitch.value), float(self.yaw.value), c.roll)

    def _new_sketch(self, action):
        """An empty sketch in the storyboard camera, the size of the storyboard's sketches."""
        return Sketch(action=action, camera=self.camera, size=self._sketch_size)

    def _draft(self, frame):
        sketch = (copy.deepcopy(frame.sketch) if frame.sketch is not None
                  else self._new_sketch(frame.action))
        sketch.action = frame.action
        return _Draft(frame.action, frame.keypose_at, sketch, frame)

    def set_storyboard(self, storyboard):
        """Edit ``storyboard`` (a :class:`~physlab.motion.storyboard.Storyboard`): its frames,
        title and camera replace the editor's; the last animation is dropped."""
        if not isinstance(storyboard, Storyboard):
            raise TypeError(f"storyboard must be a Storyboard, got {type(storyboard).__name__}")
        cam = storyboard.camera or DEFAULT_CAMERA
        self._camera0 = cam
        for s, v in ((self.pitch, cam.pitch), (self.yaw, cam.yaw)):
            s.min, s.max = min(s.min, v), max(s.max, v)
            s.value = v
        self.title.value = storyboard.title
        self._sketch_size = next((f.sketch.size for f in storyboard.frames
                                  if f.sketch is not None), NEW_SKETCH_SIZE)
        self.selected = None
        self.drafts = [self._draft(f) for f in storyboard.frames]
        self._drop_animation()
        self.select(0)

    def _pull(self):
        """Copy the canvas's sketch and the frame controls into the selected draft."""
        if self.selected is None or self.canvas is None:     # no frame, or switching frames
            return
        d = self.drafts[self.selected]
        d.sketch = self.canvas.sketch                  # the canvas's Load replaces it
        d.action = self.action.value
        d.keypose_at = self.keypose_at.value

    def _frame(self, i):
        """The StoryboardFrame of draft ``i`` (module docstring); ValueError naming it."""
        d = self.drafts[i]
        if d.signature() == d.start and d.frame is not None:
            return d.frame
        base = d.frame
        try:
            if _drawn(d.sketch):
                d.sketch.action = d.action
                f = StoryboardFrame.from_sketch(d.sketch)
                traj = any(s.kind == "trajectory" for s in d.sketch.strokes)
                kw = dict(keypose_2d=f.keypose_2d, trajectories_2d=f.trajectories_2d,
                          camera=f.camera, sketch=d.sketch,
                          keypose_at=f.keypose_at if traj else d.keypose_at)
                if base is not None:
                    kw.update(keypose_3d=base.keypose_3d, trajectories_3d=base.trajectories_3d)
            else:
                kw = dict(keypose_at=d.keypose_at)
                if base is not None and base.sketch is None:     # conditions from a file
                    kw.update(keypose_2d=base.keypose_2d, trajectories_2d=base.trajectories_2d,
                              keypose_3d=base.keypose_3d, trajectories_3d=base.trajectories_3d,
                              camera=base.camera)
                elif base is not None:                          # the sketch was cleared
                    kw.update(keypose_3d=base.keypose_3d, trajectories_3d=base.trajectories_3d)
            return StoryboardFrame(action=d.action, **kw)
        except (TypeError, ValueError) as e:
            raise type(e)(f"frame {i + 1} ({d.action!r}): {e}") from None

    @property
    def storyboard(self):
        self._pull()
        if not self.drafts:
            raise ValueError("the storyboard is empty: press Add frame")
        frames = [self._frame(i) for i in range(len(self.drafts))]
        return Storyboard(frames, camera=self.camera, title=self.title.value)

    # ------------------------------------------------------------------ the strip
    def _thumb(self, i):
        """PNG bytes of draft ``i``'s thumbnail: its canvas sketch, else the conditions of
        the frame it came from (when that frame had no sketch), else its action."""
        d = self.drafts[i]
        base = d.frame if d.frame is not None and d.frame.sketch is None else None
        return png_bytes(_thumbnail(d.action, str(i + 1), d.sketch, base, self.camera,
                                    THUMB_SIZE, i == self.selected))

    def _refresh_strip(self):
        import ipywidgets as w

        n = len(self.drafts)
        while len(self._slots) < n:
            k = len(self._slots)
            img = w.Image(format="png", layout=w.Layout(width=f"{THUMB_SIZE[0]}px"))
            b = w.Button(layout=w.Layout(width=f"{THUMB_SIZE[0]}px"))
            b.on_click(lambda _b, k=k: self._guard(self.select, k))
            self._slots.append((img, b, w.VBox([img, b], layout=w.Layout(margin="0 4px 0 0"))))
        for _img, _b, box in self._slots[n:]:
            _close(box)
        self._slots = self._slots[:n]
        for i in range(n):
            self._refresh_thumb(i)
        self.strip.children = [box for _i, _b, box in self._slots]
        self.delete_button.disabled = n == 0
        self.left_button.disabled = not self.selected
        self.right_button.disabled = self.selected is None or self.selected >= n - 1

    def _refresh_thumb(self, i):
        img, b, _box = self._slots[i]
        d = self.drafts[i]
        img.value = self._thumb(i)
        b.description = f"{i + 1}: {textwrap.shorten(d.action, 14, placeholder='…')}"
        b.tooltip = f"select frame {i + 1}: {d.action}"
        b.button_style = "info" if i == self.selected else ""

    @property
    def frame_buttons(self):
        """The strip's select buttons, one per frame."""
        return [b for _i, b, _box in self._slots]

    def _edited(self):
        """The action or keypose_at of the selected frame changed."""
        if self.selected is not None and self.canvas is not None and self._slots:
            self._pull()
            self._refresh_thumb(self.selected)

    def _canvas_changed(self):
        if self.selected is not None:
            self._pull()
            self._refresh_thumb(self.selected)
            self._note()

    # ------------------------------------------------------------------ frame operations
    def select(self, i):
        """Show frame ``i`` (0-based) in the canvas."""
        n = len(self.drafts)
        if not isinstance(i, (int, np.integer)) or not 0 <= i < n:
            raise IndexError(f"frame {i} out of range: the storyboard has {n} frames")
        self._pull()
        self.selected = int(i)
        self._show_canvas(self.drafts[self.selected])
        self._refresh_strip()
        self._say(f"frame {self.selected + 1} of {n}: draw in the canvas, or just describe "
                  "the action")

    def add_frame(self, action=NEW_ACTION):
        """Insert a text-only frame after the selected one (at the end without a selection)
        and select it."""
        self._pull()
        at = len(self.drafts) if self.selected is None else self.selected + 1
        self.drafts.insert(at, _Draft(action, "first", self._new_sketch(action)))
        self.selected = None
        self.select(at)
        self._say(f"added frame {at + 1}: type its action, draw if you like")

    def delete_frame(self):
        """Delete the selected frame (select its neighbour)."""
        if self.selected is None:
            raise ValueError("no frame selected: the storyboard is empty")
        i = self.selected
        del self.drafts[i]
        self.selected = None
        if self.drafts:
            self.select(min(i, len(self.drafts) - 1))
        else:
            self._show_canvas(None)
            self._refresh_strip()
        self._say(f"deleted frame {i + 1}; {len(self.drafts)} left"
                  + ("" if self.drafts else ": press Add frame"))

    def move(self, step):
        """Move the selected frame ``step`` places (−1 earlier, +1 later)."""
        if self.selected is None:
            raise ValueError("no frame selected: the storyboard is empty")
        self._pull()
        i, j = self.selected, self.selected + int(step)
        if not 0 <= j < len(self.drafts):
            raise ValueError(f"frame {i + 1} is already the {'first' if j < 0 else 'last'}")
        self.drafts[i], self.drafts[j] = self.drafts[j], self.drafts[i]
        self.selected = j
        self._refresh_strip()
        self.frame_title.value = self._frame_heading()
        self._say(f"moved frame {i + 1} to place {j + 1}")

    # ------------------------------------------------------------------ the canvas
    def _frame_heading(self):
        if self.selected is None:
            return "<b>no frame</b>: press Add frame"
        return f"<b>frame {self.selected + 1} of {len(self.drafts)}</b>"

    def _note(self):
        """Say where the selected frame's conditions come from; with trajectory strokes the
        ``keypose at`` dropdown shows (and may not change) what they imply."""
        d = self.drafts[self.selected]
        f = d.frame
        traj = any(s.kind == "trajectory" for s in d.sketch.strokes)
        self.keypose_at.disabled = traj
        if traj:
            try:
                at = d.sketch.trajectories_px()[1]
            except ValueError:                     # e.g. two strokes at one joint: said later
                at = None
            if at is not None and at != self.keypose_at.value:
                self.keypose_at.value = at
        if _drawn(d.sketch):
            text = ("drawn: its camera is the canvas's pitch / yaw"
                    + ("; keypose at follows the trajectory strokes" if traj else ""))
        elif f is not None and f.sketch is None and (f.has_2d or f.keypose_3d is not None
                                                     or f.trajectories_3d):
            what = [k for k in ("keypose_2d", "trajectories_2d", "keypose_3d",
                                "trajectories_3d") if getattr(f, k) is not None]
            text = (f"conditions from the file ({', '.join(what)}); drawing here replaces the "
                    f"2D ones")
        else:
            text = "text only: the action alone drives this clip (draw to add conditions)"
        self.frame_note.value = f'<span style="color:#555">{html.escape(text)}</span>'

    def _show_canvas(self, draft):
        from physlab.viz.sketch_canvas import SketchCanvas

        for link in self._links:
            link.unlink()
        self._links = []
        old = self.canvas
        self.canvas = None
        if draft is None:
            self.canvas_box.children = []
            self.frame_note.value = ""
        else:
            self.action.value = draft.action
            self.keypose_at.value = draft.keypose_at
            c = SketchCanvas(sketch=draft.sketch, backend=self.backend)
            for hidden in (c.action, c.go, c.result):      # one action box; the editor generates
                hidden.layout.display = "none"
            self._links = [_link(self.action, c.action)]
            c.on_change(lambda _c: self._canvas_changed())
            self.canvas = c
            self.canvas_box.children = [c.widget]
        self.frame_title.value = self._frame_heading()
        for t in (self.action, self.keypose_at):
            t.disabled = draft is None
        if draft is not None:
            self._note()
        if old is not None:
            _close(old.widget)

    # ------------------------------------------------------------------ files
    def save(self, path=None):
        """Write the storyboard as JSON to ``path`` (default: the file box). Returns the
        Path."""
        sb = self.storyboard
        p = Path(sb.save(path if path is not None else self.file.value))
        self._say(f"saved {len(sb)} frames to {html.escape(str(p))}")
        return p

    def load(self, path=None):
        """Read a storyboard JSON from ``path`` (default: the file box) into the editor."""
        p = path if path is not None else self.file.value
        sb = Storyboard.load(p)
        self.set_storyboard(sb)
        self._say(f"loaded {len(sb)} frames from {html.escape(str(p))}")
        return sb

    # ------------------------------------------------------------------ generate, export
    def _drop_animation(self):
        self.animation = self.animated = None
        self.preview.value = b""
        self.preview.layout.display = self.preview_caption.layout.display = "none"
        self.timeline.value = ""
        self.files.value = ""
        self.exported = {}

    def _work(self, f, *args, **kwargs):
        """Run ``f`` with the progress Output capturing its tqdm bar; warnings are returned
        (shown in the status line, never as stderr)."""
        self.progress.clear_output()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                with self.progress:
                    out = f(*args, **kwargs)
            finally:
                self.progress.clear_output()
        return out, [str(c.message) for c in caught if not issubclass(c.category, _QUIET)]

    def generate(self):
        """Generate every frame's clip, join them, show the preview; returns the
        :class:`~physlab.motion.storyboard.StoryboardAnimation`."""
        from physlab.motion.storyboard import animate_storyboard

        sb = self.storyboard
        if self.canvas is not None:
            self.canvas.redraw()                   # joints snapped while building the frame
        n = len(sb)
        method, transition = self.method.value, int(self.transition.value)
        if transition == 0:                                 # a plain cut
            method, transition = "concat", TRANSITION
        self._say(f"generating {n} clip(s) and {n - 1} junction(s)…")
        t0 = time.perf_counter()
        anim, notes = self._work(animate_storyboard, sb, transition=transition,
                                 seed=int(self.seed.value), progress=True, method=method,
                                 **self.options)
        t1 = time.perf_counter()
        self.animation, self.animated = anim, copy.deepcopy(sb)   # the canvas edits sb's sketch
        self.files.value, self.exported = "", {}
        self._say(f"generated {len(anim.joints)} frames in {t1 - t0:.1f} s; rendering the "
                  "preview…")
        frames, more = self._work(preview_frames, sb, anim, backend=self.backend)
        self.preview.value = _gif_bytes(frames, 20 / PREVIEW_EVERY)
        self.preview.layout.display = self.preview_caption.layout.display = None
        self.timeline.value = _timeline(anim, sb)
        msg = (f"generated {len(anim.joints)} frames ({len(anim.joints) / 20:.1f} s at 20 fps;"
               f" {n} clip(s), blending {method}) in {t1 - t0:.1f} s, preview in "
               f"{time.perf_counter() - t1:.1f} s")
        self._say(msg + _notes(notes + more))
        return anim

    def export(self):
        """Write the last animation and its storyboard into the export folder
        (:func:`~physlab.viz.storyboard_view.export_storyboard`); returns ``{format: Path}``."""
        from physlab.viz.storyboard_view import export_storyboard

        if self.animation is None:
            raise ValueError("nothing to export yet: press Generate first")
        folder = self.export_dir.value.strip()
        if not folder:
            raise ValueError("the export folder is empty: type a folder name")
        changed = ""
        try:
            if self.storyboard.to_dict() != self.animated.to_dict():
                changed = "; the storyboard changed since Generate: these files hold the " \
                          "generated one (Generate again to export the edits)"
        except (TypeError, ValueError):
            changed = "; the storyboard has errors now: exported the generated one"
        self._say(f"exporting to {html.escape(folder)}…")
        t0 = time.perf_counter()
        paths, notes = self._work(export_storyboard, self.animated, self.animation, folder,
                                  formats=self.export_formats, backend=self.backend,
                                  progress=True)
        self.exported = paths
        self.files.value = "<ul style='margin:2px 0'>" + "".join(
            f"<li><code>{html.escape(str(p))}</code> ({fmt}, {_size(p)})</li>"
            for fmt, p in paths.items()) + "</ul>"
        self._say(f"exported {len(paths)} files ({len(self.animation.joints)} frames) to "
                  f"{html.escape(folder)} in {time.perf_counter() - t0:.1f} s"
                  + html.escape(changed) + _notes(notes))
        return paths

    # ------------------------------------------------------------------ messages
    def _say(self, text, error=False):
        if error:     # plain text; frames numbered as in the strip: frames[1] -> frame 2
            text = html.escape(re.sub(r"frames\[(\d+)\]",
                                      lambda m: f"frame {int(m.group(1)) + 1}", text),
                               quote=False)
        super()._say(text, error)


def _link(a, b):
    import ipywidgets as w

    return w.link((a, "value"), (b, "value"))


def _notes(notes):
    """Warnings as a short grey postscript of the status line."""
    notes = list(dict.fromkeys(n.splitlines()[0] for n in notes if n.strip()))
    if not notes:
        return ""
    text = "; ".join(textwrap.shorten(n, 160, placeholder="…") for n in notes[:3])
    return f'<br><span style="color:#8a6d00">note: {html.escape(text)}</span>'


def _size(path):
    try:
        n = Path(path).stat().st_size
    except OSError:
        return "?"
    return f"{n / 1e6:.1f} MB" if n >= 1e5 else f"{n / 1e3:.0f} kB"
