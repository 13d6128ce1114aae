"""A sketch canvas for JupyterLab: draw a stick figure and trajectory strokes, pick the view,
type the action, press Generate, see the 3D motion and its projection over the drawing
(Sketch2Anim Sec. 3 / Fig. 3, lesson 10).

Built on **ipycanvas** (QuantStack, BSD-3): a real HTML canvas with mouse events sent to the
kernel, batched drawing (``hold_canvas``) and layers, prebuilt for JupyterLab 4 — drawing with
ipympl's matplotlib events would redraw a whole figure for every mouse move. The logic (joints
from strokes, strokes to trajectories, pixels to normalised units) lives in
:mod:`physlab.motion.sketch`; this module only draws and routes events.

Modes (toggle buttons): **pose** strokes (black), **trajectory** strokes (red), **joints**
(drag a snapped joint to fix it). Buttons: Snap joints, Undo, Clear, Generate, and Save /
Load of the sketch as JSON (:meth:`~physlab.motion.sketch.Sketch.save`). The result:
a strobe image of the 3D motion (pyvista, or matplotlib) and, on the canvas, the motion
projected in the sketch's view (blue stick figures and the pelvis path), with a readout of
how far the projected joints stay from the drawn trajectories.
"""
from __future__ import annotations

import time

import numpy as np

from physlab.motion.camera import Camera, to_pixels
from physlab.motion.sketch import Sketch, Stroke, TemplateSnapper
from physlab.motion.skeleton import JOINT_NAMES, PARENTS
from physlab.viz.canvas_widget import CanvasWidget, png_bytes

__all__ = ["SketchCanvas", "COLORS"]

#: Stroke colours on the canvas (CSS), also the colours :func:`~physlab.motion.sketch.
#: sketch_from_png` reads by default (pose black, trajectory red).
COLORS = {"pose": "#000000", "trajectory": "#dc0000", "joints": "#1f77b4",
          "motion": "rgba(31, 119, 180, 0.55)", "pelvis": "#1f77b4"}
_GRAB_PX = 12          # a click this close to a joint grabs it


class SketchCanvas(CanvasWidget):
    """The widget (``display(SketchCanvas().widget)``).

    Parameters
    ----------
    sketch : optional :class:`~physlab.motion.sketch.Sketch` to start from (e.g. loaded from
        JSON); its size sets the canvas size.
    generate : callable ``(**conditions) -> (40, 22, 3)`` joints; default
        :func:`physlab.motion.generate` (loads the shipped checkpoint on first use).
    detector : joint detector (default :class:`~physlab.motion.sketch.TemplateSnapper`).
    backend : 3D renderer for the result, ``"auto"`` | ``"pyvista"`` | ``"matplotlib"``.
    generate_options : extra keywords for ``generate`` (e.g. ``{"steps": 30}``).

    Attributes: ``sketch``, ``motion`` (the last generated joints or None), ``conditions``
    (the last keywords given to ``generate``), ``status`` (the readout text).
    :meth:`on_change` registers a callback run whenever the drawing changes.
    """

    def __init__(self, sketch=None, generate=None, detector=None, backend="auto",
                 generate_options=None):
        import ipywidgets as w
        from ipycanvas import MultiCanvas

        self.sketch = sketch if sketch is not None else Sketch()
        if not isinstance(self.sketch, Sketch):
            raise TypeError(f"sketch must be a physlab.motion.sketch.Sketch, got "
                            f"{type(self.sketch).__name__}")
        self._generate = generate
        self.detector = detector or TemplateSnapper()
        self.backend = backend
        self.options = dict(generate_options or {})
        self.motion, self.conditions = None, None
        self._drawing, self._grabbed = None, None
        self._change_callbacks = []
        W, H = self.sketch.size
        self.canvas = MultiCanvas(3, width=W, height=H)     # 0 strokes, 1 joints, 2 motion
        self.canvas.layout.border = "1px solid #bbb"
        self.mode = w.ToggleButtons(options=["pose", "trajectory", "joints"], value="pose",
                                    description="draw", style={"button_width": "96px"})
        self.action = w.Text(value=self.sketch.action, description="action")
        cam = self.sketch.camera
        self.pitch = w.FloatSlider(value=cam.pitch, min=0, max=30, step=1, description="pitch°")
        self.yaw = w.FloatSlider(value=cam.yaw, min=-45, max=45, step=1, description="yaw°")
        self.by_speed = w.Checkbox(value=False, description="speed from drawing")
        self.snap = w.Button(description="Snap joints")
        self.undo = w.Button(description="Undo")
        self.clear = w.Button(description="Clear")
        self.go = w.Button(description="Generate", button_style="primary")
        self.file = w.Text(value="sketch.json", description="file")
        self.save = w.Button(description="Save")
        self.load = w.Button(description="Load")
        self.readout = w.HTML(value="Draw a stick figure, then trajectories in red.")
        # hidden until there is a result: an empty Image shows a broken-image icon
        self.result = w.Image(format="png", layout=w.Layout(max_width="520px", display="none"))
        self._on_clicks(((self.snap, self._on_snap), (self.undo, self._on_undo),
                         (self.clear, self._on_clear), (self.go, self._on_generate),
                         (self.save, self._on_save), (self.load, self._on_load)))
        for s in (self.pitch, self.yaw):
            s.observe(lambda _c: self._guard(self._on_camera), names="value")
        self.action.observe(lambda c: setattr(self.sketch, "action", c["new"]), names="value")
        self._route_mouse(self.canvas, self._down, self._move, self._up)
        controls = w.VBox([self.mode, self.action, self.pitch, self.yaw, self.by_speed,
                           w.HBox([self.snap, self.undo]), w.HBox([self.clear, self.go]),
                           self.file, w.HBox([self.save, self.load]), self.readout])
        self.widget = w.VBox([w.HBox([self.canvas, controls]), self.result])
        self.widget.add_class("physlab-sketch-canvas")
        self.redraw()

    def on_change(self, callback, remove=False):
        """Call ``callback(self)`` after every change of the sketch: a stroke drawn (or
        :meth:`add_stroke`), a joint dragged, Snap, Undo, Clear, Load, the camera sliders
        (``remove=True`` unregisters it). Errors it raises show in the readout."""
        if not callable(callback):
            raise TypeError(f"callback must be callable, got {callback!r}")
        if remove:
            self._change_callbacks.remove(callback)
        else:
            self._change_callbacks.append(callback)

    def _changed(self):
        for f in list(self._change_callbacks):
            self._guard(f, self)

    # -- drawing
    def redraw(self):
        from ipycanvas import hold_canvas

        strokes, joints = self.canvas[0], self.canvas[1]
        with hold_canvas():
            strokes.clear()
            strokes.fill_style = "#ffffff"
            strokes.fill_rect(0, 0, *self.sketch.size)
            strokes.line_width, strokes.line_cap, strokes.line_join = 3, "round", "round"
            for s in self.sketch.strokes:
                strokes.stroke_style = COLORS[s.kind]
                if len(s.points) > 1:
                    strokes.stroke_lines(s.points.tolist())
            joints.clear()
            if self.sketch.joints is not None:
                self._draw_skeleton(joints, self.sketch.joints, COLORS["joints"], dots=True)

    @staticmethod
    def _draw_skeleton(layer, px, color, dots=False, width=1.5):
        layer.stroke_style, layer.fill_style, layer.line_width = color, color, width
        for j in range(1, len(JOINT_NAMES)):
            layer.stroke_line(*px[PARENTS[j]], *px[j])
        if dots:
            layer.fill_circles(px[:, 0], px[:, 1], 3.5)

    def _down(self, x, y):
        p = np.array([x, y], dtype=float)
        if self.mode.value == "joints":
            if self.sketch.joints is None:
                raise ValueError("no joints yet: press Snap joints first")
            d = np.linalg.norm(self.sketch.joints - p, axis=1)
            self._grabbed = int(np.argmin(d)) if d.min() <= _GRAB_PX else None
            return
        self._drawing = ([p], [time.perf_counter()])

    def _move(self, x, y):
        if self._grabbed is not None:
            self.sketch.joints[self._grabbed] = (x, y)
            self.redraw()
            return
        if self._drawing is None:
            return
        pts, ts = self._drawing
        p = np.array([x, y], dtype=float)
        if np.linalg.norm(p - pts[-1]) < 1.5:
            return
        layer = self.canvas[0]
        layer.stroke_style, layer.line_width, layer.line_cap = COLORS[self.mode.value], 3, "round"
        layer.stroke_line(*pts[-1], *p)
        pts.append(p)
        ts.append(time.perf_counter())

    def _up(self, x, y):
        if self._grabbed is not None:
            self._grabbed = None
            self._say("moved a joint; Generate when the figure looks right")
            self._changed()
            return
        if self._drawing is None:
            return
        pts, ts = self._drawing
        self._drawing = None
        if len(pts) < 2:
            return
        self.add_stroke(np.array(pts), self.mode.value, np.array(ts) - ts[0])

    # -- actions (also callable from code)
    def add_stroke(self, points, kind="pose", times=None):
        """Add a stroke (pixels) as if drawn; pose strokes drop the snapped joints (snap
        again)."""
        self.sketch.strokes.append(Stroke(points, kind, times))
        if kind == "pose":
            self.sketch.joints = None
        self.canvas[2].clear()
        self.redraw()
        n = {k: sum(s.kind == k for s in self.sketch.strokes) for k in ("pose", "trajectory")}
        self._say(f"{n['pose']} pose and {n['trajectory']} trajectory strokes")
        self._changed()

    def _on_snap(self):
        self.sketch.keypose(self.detector)
        self.redraw()
        self._say("joints snapped to the figure (blue); drag any that are wrong in "
                  "'joints' mode")
        self._changed()

    def _on_undo(self):
        if self.sketch.strokes:
            s = self.sketch.strokes.pop()
            if s.kind == "pose":
                self.sketch.joints = None
        self.canvas[2].clear()
        self.redraw()
        self._changed()

    def _on_clear(self):
        self.sketch.strokes.clear()
        self.sketch.joints = None
        self.motion = None
        self.result.value = b""
        self.result.layout.display = "none"
        self.canvas[2].clear()
        self.redraw()
        self._say("cleared")
        self._changed()

    def _on_save(self):
        path = self.sketch.save(self.file.value)
        self._say(f"saved the sketch to {path}")

    def _on_load(self):
        from physlab.motion.sketch import Sketch

        sk = Sketch.load(self.file.value)
        if tuple(sk.size) != tuple(self.sketch.size):
            raise ValueError(f"{self.file.value} is a {sk.size[0]}x{sk.size[1]} sketch; this "
                             f"canvas is {self.sketch.size[0]}x{self.sketch.size[1]}")
        self.sketch, self.motion = sk, None
        self.action.value = sk.action
        self.pitch.value, self.yaw.value = sk.camera.pitch, sk.camera.yaw
        self.canvas[2].clear()
        self.redraw()
        self._say(f"loaded {self.file.value}")
        self._changed()

    def _on_camera(self):
        c = self.sketch.camera
        self.sketch.camera = Camera(c.scale, float(self.pitch.value), float(self.yaw.value),
                                    c.roll)
        self._changed()

    def _on_generate(self):
        self.generate()

    def generate(self):
        """Generate from the sketch, draw the result; returns the joints."""
        cond = self.sketch.conditions(by_speed=bool(self.by_speed.value),
                                      detector=self.detector)
        self.redraw()
        self._say("generating…")
        gen = self._generate
        if gen is None:
            from physlab.motion import generate as gen
        kw = {k: v for k, v in cond.items() if v is not None}
        self.conditions = cond
        self.motion = np.asarray(gen(**kw, **self.options))
        self._show_result()
        return self.motion

    def _show_result(self):
        from physlab.viz.view3d import strobe

        x = self.motion
        proj = self.projected_motion_px()                                     # (40, 22, 2)
        layer = self.canvas[2]
        from ipycanvas import hold_canvas

        with hold_canvas():
            layer.clear()
            for f in range(0, len(x), 8):
                self._draw_skeleton(layer, proj[f], COLORS["motion"])
            layer.stroke_style, layer.line_width = COLORS["pelvis"], 2
            layer.stroke_lines(proj[:, 0].tolist())
        err = self.trajectory_error_px(proj)
        cond = self.conditions
        self.result.value = png_bytes(strobe(x, every=8, size=(520, 300),
                                            backend=self.backend))
        self.result.layout.display = None
        msg = f"generated “{cond['action']}”"
        if err:
            msg += "; projected joint vs stroke: " + ", ".join(
                f"{k} {v:.1f} px" for k, v in err.items())
        self._say(msg)

    def _pixel_trajectories(self):
        return self.sketch.trajectories_px(by_speed=bool(self.by_speed.value))

    def projected_motion_px(self, joints=None):
        """``(40, 22, 2)`` canvas pixels of a motion (default: the last generated) seen from the
        sketch's camera, placed as the sketch's conditions place it."""
        x = self.motion if joints is None else np.asarray(joints, dtype=float)
        if x is None:
            raise ValueError("no motion yet: press Generate (or call generate()) first")
        origin, ppu = self.sketch.pixel_frame(*self._pixel_trajectories())
        return to_pixels(self.sketch.camera.project(x), origin, ppu)

    def trajectory_error_px(self, projected=None):
        """Mean pixel distance between each drawn trajectory and the same joint of the
        projected motion (default: :meth:`projected_motion_px` of the last motion) over the
        frames the stroke covers: ``{joint_name: px}``."""
        if projected is None:
            projected = self.projected_motion_px()
        trajs, at = self._pixel_trajectories()
        out = {}
        for name, pts in trajs.items():
            j = JOINT_NAMES.index(name)
            n = len(pts)
            frames = np.arange(n) if at == "first" else np.arange(len(projected) - n,
                                                                   len(projected))
            out[name] = float(np.linalg.norm(projected[frames, j] - pts, axis=1).mean())
        return out
