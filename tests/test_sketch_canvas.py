"""The sketch canvas in a kernel (the browser test drives it with the mouse): events build
strokes, Snap joints, dragging a joint, Undo / Clear, Save / Load, Generate with a stand-in
generator (the projected result is compared with the drawn stroke), errors in the readout."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("ipycanvas")

from physlab.motion.camera import Camera  # noqa: E402
from physlab.motion.sketch import Sketch, template_pose  # noqa: E402
from physlab.viz.sketch_canvas import SketchCanvas  # noqa: E402

HEAD = [(150 + 16 * np.cos(a), 110 + 16 * np.sin(a)) for a in np.linspace(0, 2 * np.pi, 25)]
FIGURE = [HEAD, [(150, 128), (150, 225)], [(110, 205), (150, 145), (190, 205)],
          [(150, 225), (132, 335)], [(150, 225), (168, 335)]]


def _drag(c, points):
    """Mouse events as the canvas delivers them (through the error guard)."""
    c._guard(c._down, *points[0])
    for p in points[1:]:
        c._guard(c._move, *p)
    c._guard(c._up, *points[-1])


def _walker(sketch):
    """A stand-in generator: the template standing still, its pelvis following the drawn
    pelvis trajectory exactly (in 3D, from the 2D stroke by the sketch's own frame)."""
    def gen(action, keypose_2d=None, trajectories_2d=None, camera=None, keypose_at="first",
            **_):
        x = np.repeat(template_pose()[None], 40, axis=0)
        uv = trajectories_2d["pelvis"]                                   # (40, 2) units, front view
        x[:, :, 0] += (uv[:, 0] - uv[0, 0])[:, None]
        return x
    return gen


def test_drawing_snapping_dragging_and_generating(tmp_path):
    c = SketchCanvas(Sketch(camera=Camera()))
    c._generate = _walker(c.sketch)
    for stroke in FIGURE:
        _drag(c, [(x, y) for x, y in stroke])
    assert len(c.sketch.strokes) == 5 and c.status.endswith("5 pose and 0 trajectory strokes</span>")
    c.mode.value = "joints"
    c._guard(c._down, 10, 10)                                  # nothing to grab yet
    assert "press Snap joints first" in c.status
    c.snap.click()
    assert c.sketch.joints is not None and "snapped" in c.status
    head = c.sketch.joints[15].copy()
    _drag(c, [tuple(head), (head[0] + 5, head[1] - 4)])        # drag the head joint
    np.testing.assert_allclose(c.sketch.joints[15], head + [5, -4])
    c.mode.value = "trajectory"
    p0 = c.sketch.joints[0]
    stroke = [(p0[0] + 10 * k, p0[1]) for k in range(25)]     # from the pelvis, to the right
    _drag(c, stroke)
    assert c.result.layout.display == "none"                  # no broken-image icon before
    x = c.generate()
    assert x.shape == (40, 22, 3) and c.conditions["keypose_at"] == "first"
    assert c.result.layout.display is None
    err = c.trajectory_error_px()
    assert err["pelvis"] < 0.5 and "pelvis" in c.status      # the stand-in follows exactly
    assert c.result.value[:4] == b"\x89PNG"
    c.file.value = str(tmp_path / "s.json")
    c.save.click()
    c.clear.click()
    assert not c.sketch.strokes and c.status.endswith("cleared</span>") and not c.result.value
    assert c.result.layout.display == "none"
    c.load.click()
    assert len(c.sketch.strokes) == 6 and c.sketch.joints is not None
    c.undo.click()
    assert len(c.sketch.strokes) == 5
    c.file.value = str(tmp_path / "missing.json")
    c.load.click()
    assert "FileNotFoundError" in c.status or "No such file" in c.status
    c.clear.click()
    c.go.click()                                               # nothing drawn: an error, shown
    assert "the sketch is empty" in c.status


def test_on_change_runs_after_every_change_of_the_drawing(tmp_path):
    """Strokes, a dragged joint, Snap, Undo, Clear, Load and the camera each call the
    registered callbacks once (with the canvas); a removed callback is not called; a
    callback's error shows in the readout; a non-callable is refused."""
    c = SketchCanvas(Sketch(camera=Camera()))
    seen, other = [], []
    c.on_change(lambda canvas: seen.append(len(canvas.sketch.strokes)))
    c.on_change(other.append)
    for stroke in FIGURE:
        _drag(c, stroke)
    assert seen == [1, 2, 3, 4, 5] and other == [c] * 5
    c.on_change(other.append, remove=True)
    c.snap.click()
    c.mode.value = "joints"
    head = c.sketch.joints[15].copy()
    _drag(c, [tuple(head), (head[0] + 5, head[1] - 4)])
    c.undo.click()
    c.pitch.value = 20.0
    assert seen == [1, 2, 3, 4, 5, 5, 5, 4, 4] and len(other) == 5
    c.sketch.save(tmp_path / "s.json")
    c.file.value = str(tmp_path / "s.json")
    c.clear.click()
    assert seen[-1] == 0
    n = len(seen)
    c.load.click()
    assert seen[-1] == 4 and len(seen) > n
    c._drawing = None
    c.mode.value = "pose"
    _drag(c, [(10, 10), (10, 10)])                         # a click: no stroke, no change
    assert seen[-1] == 4

    def broken(_canvas):
        raise ValueError("the callback failed")
    c.on_change(broken)
    c.undo.click()
    assert "the callback failed" in c.status
    with pytest.raises(TypeError, match="callback must be callable"):
        c.on_change("not a function")
