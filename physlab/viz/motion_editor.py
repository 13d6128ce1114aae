"""A 3D motion editor for JupyterLab: drag a generated clip's trajectory points and keypose
joints in a top and a side view, then generate again from the edited conditions
(Sketch2Anim Sec. 7.4, Fig. 11).

Sketch2Anim's generator also takes 3D keyposes and trajectories, so a clip it made can be
edited through its own conditions: :func:`~physlab.motion.editing.extract_conditions` reads the
keypose and the joint paths off the clip, the user moves a few of them
(:func:`~physlab.motion.editing.drag_trajectory` bends a path smoothly around the dragged
sample, :func:`~physlab.motion.editing.move_joint` moves one keypose joint), and
:func:`~physlab.motion.editing.regenerate` makes a new clip that follows the edited points.
This module only draws and routes mouse events; the editing lives in
:mod:`physlab.motion.editing`.

Two orthogonal views on one **ipycanvas** canvas (like :mod:`~physlab.viz.sketch_canvas`):
the **top** view (the floor plan: ``x`` right, ``z`` up the canvas — seen from below the floor,
so a character walking up the canvas has its left side, ``+x``, on the right) and the **side**
view (``z`` right, ``y`` up). Both show the clip as stick figures every few frames, the edited
trajectory samples (every 4th sample and the last one as a draggable handle, one colour per
joint) and the keypose (orange). A drag in a view moves the two coordinates that view shows
and keeps the third. The mapping between canvas pixels and metres is a :class:`View`;
:func:`fit_views`, :func:`pick`, :func:`handle_indices`, :func:`tick_step` and
:func:`condition_errors` are plain functions over arrays.

Controls: the action text, which joints' paths are conditions (checkboxes), drag
``trajectory`` | ``keypose``, keypose on / off and at the ``first`` | ``last`` frame, the seed,
the drag radius (samples, Gaussian falloff), Regenerate, Undo, Reset, and Save (the edited
conditions as JSON, a frame that :meth:`~physlab.motion.storyboard.StoryboardFrame.from_dict`
reads). The readout gives, after Regenerate, the mean distance (cm) of the new clip's joints to
the edited trajectory points and to the keypose.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from physlab.motion.dataset import TRAJECTORY_JOINT_NAMES
from physlab.motion.editing import (DRAG_RADIUS, drag_trajectory, extract_conditions,
                                    move_joint, regenerate)
from physlab.motion.skeleton import JOINT_NAMES, PARENTS, joint_index
from physlab.viz.canvas_widget import CanvasWidget

__all__ = ["MotionEditor", "View", "VIEW_AXES", "COLORS", "fit_views", "view_at", "pick",
           "handle_indices", "tick_step", "condition_errors"]

#: World axes (0 = x, 1 = y, 2 = z) drawn to the right and up the canvas in each view.
VIEW_AXES = {"top": (0, 2), "side": (2, 1)}
#: Titles and axis names of the views.
VIEW_TITLES = {"top": "top view (floor plan)", "side": "side view"}
AXIS_NAMES = ("x", "y", "z")
#: CSS colours: one per trajectory joint, the keypose, the clip's stick figures, the grid.
COLORS = {"pelvis": "#d62728", "left_foot": "#2ca02c", "right_foot": "#1f77b4",
          "head": "#9467bd", "left_wrist": "#8c564b", "right_wrist": "#e377c2",
          "keypose": "#ff7f0e", "figure": "rgba(70, 70, 90, {a})", "grid": "#e6e6e6",
          "axis": "#888888", "text": "#333333", "floor": "#b5a58c", "grab": "#000000"}
#: A mouse down this close (canvas px) to a handle grabs it.
PICK_PX = 10.0
#: Every HANDLE_EVERY-th trajectory sample (and the last) is a draggable handle.
HANDLE_EVERY = 4
#: Stick figures drawn per view.
N_FIGURES = 6
#: Space around each view's plot area for its title and tick labels (canvas px).
_PAD = {"left": 44, "right": 10, "top": 26, "bottom": 36}
_GAP = 14          # between the two panels
_MIN_PLOT_PX = 150  # narrowest plot area (so the title fits)


# ---------------------------------------------------------------------------- pure geometry
@dataclass(frozen=True)
class View:
    """One orthographic panel: world axes ``axes`` = (right, up) drawn in the plot rectangle
    ``rect`` = (left, top, width, height) canvas px (y down), ``center`` (2,) m along
    ``axes`` at the rectangle's centre, ``scale`` px per metre (both axes)."""

    name: str
    axes: tuple
    rect: tuple
    center: tuple
    scale: float

    def to_canvas(self, points):
        """World points (..., 3) m → canvas pixels (..., 2) (x right, y down)."""
        P = np.asarray(points, dtype=float)
        a, b = self.axes
        left, top, w, h = self.rect
        x = left + w / 2 + (P[..., a] - self.center[0]) * self.scale
        y = top + h / 2 - (P[..., b] - self.center[1]) * self.scale
        return np.stack([x, y], axis=-1)

    def to_metres(self, x, y):
        """Canvas pixel ``(x, y)`` → (2,) m along the view's ``axes`` (right, up)."""
        left, top, w, h = self.rect
        return np.array([self.center[0] + (x - left - w / 2) / self.scale,
                         self.center[1] - (y - top - h / 2) / self.scale])

    def contains(self, x, y, pad=0.0):
        """Whether canvas pixel ``(x, y)`` lies in the plot rectangle grown by ``pad`` px."""
        left, top, w, h = self.rect
        return left - pad <= x <= left + w + pad and top - pad <= y <= top + h + pad

    def bounds(self):
        """``((lo_right, hi_right), (lo_up, hi_up))`` m: what the plot rectangle shows."""
        left, top, w, h = self.rect
        lo, hi = self.to_metres(left, top + h), self.to_metres(left + w, top)
        return (lo[0], hi[0]), (lo[1], hi[1])


def fit_views(points, size=(760, 440), margin=0.3):
    """The top and side :class:`View` that show ``points`` side by side on a canvas of
    ``size`` = (W, H) px, at one scale (px per m) for both, with ``margin`` m around the points
    (0.1 m below the floor, ``y = 0``, which the side view always shows). The top view gets the
    width its ``x`` range needs (at least ``_MIN_PLOT_PX``), the side view the rest.

    points : (..., 3) m. Returns ``{"top": View, "side": View}``.
    """
    P = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(P) == 0 or not np.all(np.isfinite(P)):
        raise ValueError("fit_views needs finite (n, 3) points in metres")
    W, H = size
    lo, hi = P.min(axis=0) - margin, P.max(axis=0) + margin
    lo[1] = min(lo[1] + margin, 0.0) - 0.1                 # the floor, just below it
    rng = np.maximum(hi - lo, 0.2)                         # (3,) m
    plot_h = H - _PAD["top"] - _PAD["bottom"]
    fixed_w = 2 * (_PAD["left"] + _PAD["right"]) + _GAP
    s = min(plot_h / rng[2], plot_h / rng[1], (W - fixed_w - _MIN_PLOT_PX) / rng[2],
            (W - fixed_w) / (rng[0] + rng[2]))
    if s <= 0:
        raise ValueError(f"canvas size {size} is too small for two views")
    top_w = float(max(s * rng[0], _MIN_PLOT_PX))
    side_w = float(W - fixed_w - top_w)
    mid = (lo + hi) / 2
    top = View("top", VIEW_AXES["top"], (_PAD["left"], _PAD["top"], top_w, plot_h),
               (float(mid[0]), float(mid[2])), float(s))
    x0 = _PAD["left"] + top_w + _PAD["right"] + _GAP + _PAD["left"]
    side = View("side", VIEW_AXES["side"], (x0, _PAD["top"], side_w, plot_h),
                (float(mid[2]), float(mid[1])), float(s))
    return {"top": top, "side": side}


def view_at(views, x, y, pad=PICK_PX):
    """The name of the view whose plot rectangle (grown by ``pad`` px) holds canvas pixel
    ``(x, y)``, or None."""
    for name, v in views.items():
        if v.contains(x, y, pad):
            return name
    return None


def pick(px, x, y, radius=PICK_PX):
    """Index of the point of ``px`` (n, 2) canvas pixels nearest to ``(x, y)`` if it lies
    within ``radius`` px, else None (ties: the first)."""
    P = np.asarray(px, dtype=float).reshape(-1, 2)
    if len(P) == 0:
        return None
    d = np.hypot(P[:, 0] - x, P[:, 1] - y)
    i = int(np.argmin(d))
    return i if d[i] <= radius else None


def handle_indices(n, every=HANDLE_EVERY):
    """The samples of an ``n``-sample trajectory that are drag handles: every ``every``-th and
    the last. Returns an int array."""
    if n < 1:
        return np.zeros(0, dtype=int)
    return np.unique(np.r_[np.arange(0, n, every), n - 1])


def tick_step(scale, min_px=45.0):
    """The grid spacing (m) from (0.1, 0.25, 0.5, 1, 2, 5, 10) whose ticks lie at least
    ``min_px`` apart at ``scale`` px per metre."""
    for step in (0.1, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0):
        if step * scale >= min_px:
            return step
    return 10.0


def condition_errors(joints, conditions):
    """How well a clip meets 3D conditions: the mean distance (m) between each conditioned
    joint and its trajectory samples over the frames they cover (the first ``t_r`` frames for
    ``keypose_at = "first"``, the last ``t_r`` for ``"last"``) and the mean joint distance to
    the keypose at its frame.

    joints : (T, 22, 3) m; conditions : dict as :func:`~physlab.motion.editing.
    extract_conditions` returns (keys optional). Returns ``{joint_name: m, ...,
    "keypose": m}`` (only the conditions given).
    """
    x = np.asarray(joints, dtype=float)
    at = conditions.get("keypose_at", "first")
    out = {}
    for name, path in (conditions.get("trajectories_3d") or {}).items():
        p = np.asarray(path, dtype=float)
        frames = slice(0, len(p)) if at == "first" else slice(len(x) - len(p), len(x))
        out[name] = float(np.linalg.norm(x[frames, joint_index(name)] - p, axis=-1).mean())
    if conditions.get("keypose_3d") is not None:
        key = x[0] if at == "first" else x[-1]
        out["keypose"] = float(np.linalg.norm(key - conditions["keypose_3d"], axis=-1).mean())
    return out


# ---------------------------------------------------------------------------- the widget
class MotionEditor(CanvasWidget):
    """Edit a clip by its 3D conditions in JupyterLab (``display(editor.widget)``, or leave
    ``editor`` as a cell's last line).

    Parameters
    ----------
    joints : (40, 22, 3) m, canonical frame, the clip to edit; None: ``generate(action,
        seed=0, **generate_options)``.
    action : str, the action text given to the generator.
    generate : callable ``(action, seed=..., keypose_3d=..., keypose_at=..., trajectories_3d=...,
        **options) -> (40, 22, 3)``; default :func:`physlab.motion.generate` (the shipped
        checkpoint, loaded on first use).
    trajectory_joints : names from :data:`~physlab.motion.dataset.TRAJECTORY_JOINT_NAMES`
        whose paths start as conditions.
    generate_options : dict of extra keywords for ``generate`` (e.g. ``{"steps": 20}``).
    keypose : bool, start with the keypose as a condition; keypose_at : ``"first"`` |
        ``"last"``.
    size : (W, H) canvas pixels; file : the path in the file box (Save).

    Attributes
    ----------
    motion : (40, 22, 3) the clip shown (the given or first one, then each regenerated one).
    conditions : (property) a copy of the edited conditions, keywords of
        :func:`~physlab.motion.editing.regenerate`.
    views : ``{"top": View, "side": View}``, the pixel ↔ metre maps of the canvas.
    errors : :func:`condition_errors` of the last regenerated clip (m), or None.
    widget : the ipywidgets box; status : the readout text.

    Raises
    ------
    ValueError / TypeError naming the argument: joints that are not a 40-frame (T, 22, 3)
    array, unknown trajectory joints, a ``generate`` that is not callable,
    ``generate_options`` that are not a dict.
    """

    shown_errors = (Exception,)     # a generator's error belongs in the readout, whatever it is

    def __init__(self, joints=None, action="a person walks", generate=None,
                 trajectory_joints=("pelvis",), generate_options=None, keypose=True,
                 keypose_at="first", size=(760, 440), file="motion_conditions.json"):
        import ipywidgets as w
        from ipycanvas import MultiCanvas

        if generate is not None and not callable(generate):
            raise TypeError(f"generate must be callable (action, seed=..., **conditions) -> "
                            f"(40, 22, 3) joints, got {type(generate).__name__}")
        if generate_options is not None and not isinstance(generate_options, dict):
            raise TypeError(f"generate_options must be a dict of keywords for generate, got "
                            f"{type(generate_options).__name__}")
        if not isinstance(action, str) or not action.strip():
            raise ValueError(f"action must be a non-empty text such as 'a person walks', got "
                             f"{action!r}")
        if isinstance(trajectory_joints, str):
            trajectory_joints = (trajectory_joints,)
        self._generate = generate
        self.options = dict(generate_options or {})
        self.size = tuple(int(v) for v in size)
        start = (self._generator()(action, seed=0, **self.options) if joints is None
                 else joints)
        first = extract_conditions(start, keypose_at, tuple(trajectory_joints))   # checks all
        self._initial = np.array(start, dtype=float)
        self.motion = self._initial.copy()
        self._start = {"keypose": bool(keypose), "keypose_at": keypose_at, "action": action,
                       "paths": tuple(trajectory_joints)}
        self._keypose = first["keypose_3d"] if keypose else None
        self._paths = dict(first["trajectories_3d"])
        self._history, self._grab, self._syncing, self.errors = [], None, False, None
        self.views = fit_views(self._content(), self.size)

        W, H = self.size
        self.canvas = MultiCanvas(3, width=W, height=H)    # 0 axes, 1 the clip, 2 conditions
        self.canvas.layout.border = "1px solid #bbb"
        self.canvas.layout.min_width = f"{W}px"
        wide = {"description_width": "initial"}
        self.action = w.Text(value=action, description="action", style=wide,
                             layout=w.Layout(width="300px"))
        self.paths = {n: w.Checkbox(value=n in self._paths, indent=False,
                                    description=f'<b style="color:{COLORS[n]}">●</b> {n}',
                                    description_allow_html=True, layout=w.Layout(width="118px"))
                      for n in TRAJECTORY_JOINT_NAMES}
        self.mode = w.ToggleButtons(options=["trajectory", "keypose"], value="trajectory",
                                    style={"button_width": "84px"},
                                    tooltips=["drag the coloured path handles",
                                              "drag the orange keypose joints"])
        self.keypose = w.Checkbox(value=bool(keypose), indent=False, layout=w.Layout(
            width="96px"), description=f'<b style="color:{COLORS["keypose"]}">●</b> keypose',
            description_allow_html=True)
        self.keypose_at = w.Dropdown(options=["first", "last"], value=keypose_at,
                                     description="at frame", style=wide,
                                     layout=w.Layout(width="140px"))
        self.seed = w.BoundedIntText(value=0, min=0, max=2 ** 31 - 1, description="seed",
                                     style=wide, layout=w.Layout(width="120px"))
        self.radius = w.IntSlider(value=DRAG_RADIUS, min=0, max=20, description="drag radius",
                                  continuous_update=False, style=wide,
                                  layout=w.Layout(width="300px"),
                                  tooltip="samples on each side that follow a dragged one")
        self.regenerate_button = w.Button(description="Regenerate", button_style="primary",
                                          tooltip="generate again from the edited conditions")
        self.undo_button = w.Button(description="Undo")
        self.reset_button = w.Button(description="Reset",
                                     tooltip="back to the first clip and its conditions")
        self.file = w.Text(value=str(file), description="file", layout=w.Layout(width="260px"))
        self.save_button = w.Button(description="Save", tooltip="write the edited conditions "
                                                                "as JSON")
        self.readout = w.HTML(layout=w.Layout(width=f"{W}px"))
        self.readout.add_class("physlab-readout")
        self._on_clicks(((self.regenerate_button, self.regenerate), (self.undo_button, self.undo),
                         (self.reset_button, self.reset), (self.save_button, self.save)))
        for n, box in self.paths.items():
            box.observe(lambda c, n=n: self._guard(self._on_path_box, n, c["new"]),
                        names="value")
        self.keypose.observe(lambda c: self._guard(self._on_keypose_box, c["new"]),
                             names="value")
        self.keypose_at.observe(
            lambda c: self._guard(self._on_keypose_at, c["new"], c["old"]), names="value")
        self.mode.observe(lambda _c: self._guard(self._draw_conditions), names="value")
        self._route_mouse(self.canvas, self._on_down, self._on_move, self._on_up)
        label = w.HTML("<b>conditions:</b>", layout=w.Layout(width="86px"))
        self.widget = w.VBox([
            self.canvas,
            w.HBox([label] + list(self.paths.values())),
            w.HBox([w.HTML("<b>drag:</b>", layout=w.Layout(width="44px")), self.mode,
                    w.HTML(layout=w.Layout(width="24px")), self.keypose, self.keypose_at]),
            w.HBox([self.action, self.seed, self.radius]),
            w.HBox([self.regenerate_button, self.undo_button, self.reset_button, self.file,
                    self.save_button]),
            self.readout])
        self.widget.add_class("physlab-motion-editor")
        self.canvas.on_client_ready(lambda: self._guard(self.redraw))
        self.redraw()
        self._say(f"drag a coloured handle (every {HANDLE_EVERY}th sample) in either view, or "
                  "the orange keypose joints in keypose mode; then Regenerate")

    # ------------------------------------------------------------------ state
    @property
    def conditions(self):
        """A copy of the edited conditions: ``keypose_at``, and ``keypose_3d`` (22, 3) m and
        ``trajectories_3d`` ``{name: (40, 3)}`` m when set."""
        c = {"keypose_at": self.keypose_at.value}
        if self._keypose is not None:
            c["keypose_3d"] = self._keypose.copy()
        if self._paths:
            c["trajectories_3d"] = {n: p.copy() for n, p in self._paths.items()}
        return c

    def _generator(self):
        if self._generate is not None:
            return self._generate
        from physlab.motion import generate

        return generate

    def _snapshot(self):
        return {"motion": self.motion, "keypose": None if self._keypose is None
                else self._keypose.copy(), "keypose_at": self.keypose_at.value,
                "paths": {n: p.copy() for n, p in self._paths.items()},
                "action": self.action.value, "errors": self.errors}

    def _restore(self, s):
        self.motion, self._keypose, self.errors = s["motion"], s["keypose"], s["errors"]
        self._paths = dict(s["paths"])
        self._syncing = True
        try:
            self.keypose_at.value = s["keypose_at"]
            self.keypose.value = s["keypose"] is not None
            self.action.value = s["action"]
            for n, box in self.paths.items():
                box.value = n in self._paths
        finally:
            self._syncing = False

    def _push(self):
        self._history.append(self._snapshot())

    def _content(self):
        """Every point the views must show: the clip, the edited paths and keypose."""
        parts = [self.motion.reshape(-1, 3)] + list(self._paths.values())
        if self._keypose is not None:
            parts.append(self._keypose)
        return np.concatenate(parts)

    def _refit_if_needed(self):
        """Fit the views again when something left them (never during a drag)."""
        P = self._content()
        for v in self.views.values():
            (r0, r1), (u0, u1) = v.bounds()
            a, b = v.axes
            if (P[:, a].min() < r0 or P[:, a].max() > r1 or P[:, b].min() < u0
                    or P[:, b].max() > u1):
                self.views = fit_views(P, self.size)
                return True
        return False

    def _say(self, text, error=False):
        # as CanvasWidget._say, with a normal line height (a long message wraps legibly)
        color = "#b00020" if error else "#333"
        self.readout.value = f'<div style="color:{color}; line-height:1.4">{text}</div>'

    # ------------------------------------------------------------------ edits
    def drag(self, name, index, point, radius=None):
        """Move sample ``index`` of the ``name`` path to ``point`` (3,) m, its neighbours
        along (:func:`~physlab.motion.editing.drag_trajectory`, ``radius`` samples, default the
        slider). Returns the new (t_r, 3) path."""
        if name not in self._paths:
            raise ValueError(f"{name!r} is not a trajectory condition; tick it first (paths: "
                             f"{', '.join(self._paths) or 'none'})")
        r = self.radius.value if radius is None else radius
        new = drag_trajectory(self._paths[name], index, point, r)
        self._push()
        self._paths[name] = new
        self._show_edit()
        return new

    def move_keypose_joint(self, joint, point):
        """Move keypose joint ``joint`` (name or index) to ``point`` (3,) m
        (:func:`~physlab.motion.editing.move_joint`)."""
        if self._keypose is None:
            raise ValueError("the keypose is off: tick 'keypose' to edit it")
        new = move_joint(self._keypose, joint, point)      # validates the point
        self._push()
        self._keypose = new
        self._show_edit()
        return new

    def _show_edit(self):
        """Draw an edit made from code (refit the views if it left them)."""
        if self._refit_if_needed():
            self.redraw()
        else:
            self._draw_conditions()

    def regenerate(self):
        """Generate again from the edited conditions
        (:func:`~physlab.motion.editing.regenerate` with this editor's generator, seed and
        options), show the new clip and the distances to the conditions. Returns (40, 22, 3);
        on an error nothing changes."""
        action = self.action.value.strip()
        if not action:
            raise ValueError("the action is empty: type what the person does, e.g. "
                             "'a person walks'")
        cond = self.conditions
        self._say(f"regenerating “{action}”…")
        t0 = time.perf_counter()
        x = np.asarray(regenerate(action, cond, seed=int(self.seed.value),
                                  generator=self._generator(), **self.options), dtype=float)
        if x.shape != self.motion.shape or not np.all(np.isfinite(x)):
            raise ValueError(f"the generator returned an array of shape {x.shape} (or with NaN); "
                             f"expected finite {self.motion.shape} joints in metres")
        self._push()
        self.motion = x
        self.errors = condition_errors(x, cond)
        self._refit_if_needed()
        self.redraw()
        parts = [f"{k} {100 * v:.1f} cm" for k, v in self.errors.items()]
        self._say(f"regenerated “{action}” (seed {self.seed.value}) in "
                  f"{time.perf_counter() - t0:.1f} s; "
                  + (f"mean distance to the edited points: {', '.join(parts)}" if parts
                     else "no conditions (the action alone)"))
        return x

    def undo(self):
        """Undo the last edit, condition switch, Regenerate or Reset."""
        if not self._history:
            self._say("nothing to undo")
            return
        self._restore(self._history.pop())
        self._refit_if_needed()
        self.redraw()
        self._say(f"undone ({len(self._history)} step(s) left to undo)")

    def reset(self):
        """Back to the first clip and the conditions read off it (undoable)."""
        self._push()
        s = self._start
        c = extract_conditions(self._initial, s["keypose_at"], s["paths"])
        self._restore({"motion": self._initial.copy(),
                       "keypose": c["keypose_3d"] if s["keypose"] else None,
                       "keypose_at": s["keypose_at"], "paths": c["trajectories_3d"],
                       "action": s["action"], "errors": None})
        self.views = fit_views(self._content(), self.size)      # the first clip's views
        self.redraw()
        self._say("reset to the first clip and its conditions")

    def to_dict(self):
        """The edited conditions and the action as a JSON-ready dict (a storyboard frame:
        ``action``, ``keypose_at``, ``keypose_3d``, ``trajectories_3d``; 10 µm rounding)."""
        c = self.conditions
        key = c.get("keypose_3d")
        return {"action": self.action.value, "keypose_at": c["keypose_at"],
                "keypose_3d": None if key is None else np.round(key, 5).tolist(),
                "trajectories_3d": {n: np.round(p, 5).tolist()
                                    for n, p in c.get("trajectories_3d", {}).items()} or None}

    def save(self, path=None):
        """Write :meth:`to_dict` as JSON to ``path`` (default: the file box), atomically;
        returns the path."""
        from physlab._io import write_json

        path = Path(self.file.value if path is None else path)
        write_json(path, self.to_dict())
        self._say(f"saved the conditions ({', '.join(self._paths) or 'no paths'}"
                  f"{', keypose' if self._keypose is not None else ''}) to {path}")
        return path

    # ------------------------------------------------------------------ controls
    def _on_path_box(self, name, on):
        if self._syncing or (name in self._paths) == on:
            return
        self._push()
        if on:
            at = self.keypose_at.value
            self._paths[name] = extract_conditions(self.motion, at, (name,))[
                "trajectories_3d"][name]
        else:
            del self._paths[name]
        self._draw_conditions()
        self._say(f"{name} path {'is now' if on else 'is no longer'} a condition")

    def _on_keypose_box(self, on):
        if self._syncing or (self._keypose is not None) == on:
            return
        self._push()
        self._keypose = self._read_keypose() if on else None
        if not on and self.mode.value == "keypose":
            self.mode.value = "trajectory"
        self._draw_conditions()
        self._say("the keypose is a condition" if on else "the keypose is off")

    def _on_keypose_at(self, at, old):
        if self._syncing:
            return
        self._history.append(dict(self._snapshot(), keypose_at=old))   # as before the change
        if self._keypose is not None:
            self._keypose = self._read_keypose()
        self._draw_conditions()
        self._say(f"keypose at the {at} frame" + (" (read off the clip)"
                                                  if self._keypose is not None else ""))

    def _read_keypose(self):
        return self.motion[0 if self.keypose_at.value == "first" else -1].copy()

    # ------------------------------------------------------------------ mouse
    def _handles(self, view):
        """``(labels, px)``: what can be grabbed in ``view`` in the current mode —
        ``("path", name, index)`` or ``("keypose", joint, joint)`` — and its (n, 2) canvas px."""
        v = self.views[view]
        if self.mode.value == "keypose":
            if self._keypose is None:
                return [], np.zeros((0, 2))
            return ([("keypose", j, j) for j in range(len(JOINT_NAMES))],
                    v.to_canvas(self._keypose))
        labels, pts = [], []
        for n, p in self._paths.items():
            for i in handle_indices(len(p)):
                labels.append(("path", n, int(i)))
                pts.append(p[i])
        return labels, v.to_canvas(np.array(pts).reshape(-1, 3))

    def _on_down(self, x, y):
        """Mouse down at canvas pixel ``(x, y)``: grab the nearest handle of the view there."""
        view = view_at(self.views, x, y)
        if view is None:
            return
        if self.mode.value == "keypose" and self._keypose is None:
            raise ValueError("the keypose is off: tick 'keypose' to drag its joints")
        labels, px = self._handles(view)
        i = pick(px, x, y)
        if i is None:
            what = ("an orange keypose joint" if self.mode.value == "keypose"
                    else "a coloured handle")
            self._say(f"nothing to grab here: press on {what} in the {view} view")
            return
        kind, name, index = labels[i]
        base = self._keypose.copy() if kind == "keypose" else self._paths[name].copy()
        self._grab = {"view": view, "kind": kind, "name": name, "index": index, "base": base,
                      "start": (x, y), "before": self._snapshot()}
        self._draw_conditions()

    def _grab_point(self, x, y):
        """The grabbed point moved by the mouse displacement since the mouse down (m)."""
        g = self._grab
        v = self.views[g["view"]]
        p = g["base"][g["index"]].copy()
        p[list(v.axes)] += v.to_metres(x, y) - v.to_metres(*g["start"])
        return p

    def _on_move(self, x, y):
        """Mouse move to canvas pixel ``(x, y)``: drag the grabbed handle (the path bends from
        its shape at the mouse down, so the falloff does not accumulate)."""
        g = self._grab
        if g is None:
            return
        p = self._grab_point(x, y)
        if g["kind"] == "keypose":
            self._keypose = move_joint(g["base"], g["index"], p)
        else:
            self._paths[g["name"]] = drag_trajectory(g["base"], g["index"], p,
                                                     self.radius.value)
        self._draw_conditions()

    def _on_up(self, x, y):
        """Mouse up at canvas pixel ``(x, y)``: end the drag (one undo step)."""
        g = self._grab
        if g is None:
            return
        self._on_move(x, y)
        p = self._grab_point(x, y)
        self._grab = None
        self._draw_conditions()                          # without the grab ring
        d = p - g["base"][g["index"]]
        if not np.any(d):
            what = (JOINT_NAMES[g["index"]] if g["kind"] == "keypose"
                    else f"{g['name']} sample {g['index']}")
            self._say(f"grabbed {what}; drag it to move it")
            return
        self._history.append(g["before"])
        what = (f"keypose {JOINT_NAMES[g['index']]}" if g["kind"] == "keypose"
                else f"{g['name']} sample {g['index']}")
        self._say(f"moved {what} by ({d[0]:+.2f}, {d[1]:+.2f}, {d[2]:+.2f}) m to "
                  f"({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m in the {g['view']} view; press "
                  "Regenerate")

    # ------------------------------------------------------------------ drawing
    def redraw(self):
        """Redraw the three layers (axes, the clip, the conditions)."""
        from ipycanvas import hold_canvas

        with hold_canvas():
            self._draw_axes()
            self._draw_motion()
            self._draw_conditions()

    def _draw_axes(self):
        layer = self.canvas[0]
        layer.clear()
        layer.fill_style = "#ffffff"
        layer.fill_rect(0, 0, *self.size)
        for v in self.views.values():
            left, top, w, h = v.rect
            (r0, r1), (u0, u1) = v.bounds()
            step = tick_step(v.scale)
            layer.line_width = 1
            layer.stroke_style = COLORS["grid"]
            rt = np.arange(np.ceil(r0 / step), np.floor(r1 / step) + 1) * step
            ut = np.arange(np.ceil(u0 / step), np.floor(u1 / step) + 1) * step
            a, b = v.axes
            for t in rt:
                px = left + w / 2 + (t - v.center[0]) * v.scale
                layer.stroke_line(px, top, px, top + h)
            for t in ut:
                py = top + h / 2 - (t - v.center[1]) * v.scale
                layer.stroke_line(left, py, left + w, py)
            if v.name == "side" and u0 <= 0 <= u1:                # the floor
                py = top + h / 2 + v.center[1] * v.scale
                layer.stroke_style, layer.line_width = COLORS["floor"], 2
                layer.stroke_line(left, py, left + w, py)
            layer.stroke_style, layer.line_width = COLORS["axis"], 1
            layer.stroke_rect(left, top, w, h)
            layer.fill_style, layer.font = COLORS["text"], "11px sans-serif"
            layer.text_align, layer.text_baseline = "center", "top"
            for t in rt:
                layer.fill_text(_tick(t), left + w / 2 + (t - v.center[0]) * v.scale,
                                top + h + 3)
            layer.fill_text(f"{AXIS_NAMES[a]} (m) →", left + w / 2, top + h + 18)
            layer.text_align, layer.text_baseline = "right", "middle"
            for t in ut:
                layer.fill_text(_tick(t), left - 4, top + h / 2 - (t - v.center[1]) * v.scale)
            layer.save()
            layer.translate(left - 34, top + h / 2)
            layer.rotate(-np.pi / 2)
            layer.text_align, layer.text_baseline = "center", "middle"
            layer.fill_text(f"{AXIS_NAMES[b]} (m) →", 0, 0)
            layer.restore()
            layer.font, layer.text_align, layer.text_baseline = ("bold 13px sans-serif", "left",
                                                                 "bottom")
            layer.fill_text(VIEW_TITLES[v.name], left, top - 6)

    def _draw_motion(self):
        layer = self.canvas[1]
        layer.clear()
        x = self.motion
        frames = np.unique(np.linspace(0, len(x) - 1, N_FIGURES).round().astype(int))
        layer.line_cap, layer.line_join = "round", "round"
        for v in self.views.values():
            for k, f in enumerate(frames):
                px = v.to_canvas(x[f])
                alpha = 0.25 + 0.5 * k / max(len(frames) - 1, 1)     # later frames darker
                layer.stroke_style = COLORS["figure"].format(a=f"{alpha:.2f}")
                layer.line_width = 1.5
                segs = np.stack([px[PARENTS[1:]], px[1:]], axis=1)      # (21, 2, 2) bones
                layer.stroke_line_segments(segs)
            for n in TRAJECTORY_JOINT_NAMES:                 # the clip's own paths, thin
                if n in self._paths:
                    layer.stroke_style, layer.line_width = COLORS[n], 1
                    layer.global_alpha = 0.45
                    layer.stroke_lines(v.to_canvas(x[:, joint_index(n)]))
                    layer.global_alpha = 1.0

    def _draw_conditions(self):
        from ipycanvas import hold_canvas

        layer = self.canvas[2]
        g = self._grab
        keymode = self.mode.value == "keypose"
        with hold_canvas():
            layer.clear()
            layer.line_cap, layer.line_join = "round", "round"
            for v in self.views.values():
                if self._keypose is not None:
                    px = v.to_canvas(self._keypose)
                    layer.stroke_style = layer.fill_style = COLORS["keypose"]
                    layer.line_width = 2.5
                    layer.stroke_line_segments(np.stack([px[PARENTS[1:]], px[1:]], axis=1))
                    layer.fill_circles(px[:, 0], px[:, 1], 4.5 if keymode else 2.5)
                    if keymode:
                        layer.stroke_style, layer.line_width = "#ffffff", 1
                        layer.stroke_circles(px[:, 0], px[:, 1], 4.5)
                for n, p in self._paths.items():
                    px = v.to_canvas(p)
                    layer.stroke_style = layer.fill_style = COLORS[n]
                    layer.line_width = 2
                    layer.stroke_lines(px)
                    layer.fill_circles(px[:, 0], px[:, 1], 1.8)
                    h = px[handle_indices(len(p))]
                    r = 3.5 if keymode else 5.5
                    layer.fill_circles(h[:, 0], h[:, 1], r)
                    layer.stroke_style, layer.line_width = "#ffffff", 1.5
                    layer.stroke_circles(h[:, 0], h[:, 1], r)
                if g is not None:                               # ring the grabbed point
                    q = (self._keypose if g["kind"] == "keypose"
                         else self._paths[g["name"]])[g["index"]]
                    c = v.to_canvas(q)
                    layer.stroke_style, layer.line_width = COLORS["grab"], 2
                    layer.stroke_circle(c[0], c[1], 9)


def _tick(t):
    """A tick label: ``0``, ``0.5``, ``-1``, ``0.25``."""
    return f"{t:.2f}".rstrip("0").rstrip(".") if abs(t) > 1e-9 else "0"
