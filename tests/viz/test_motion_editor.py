"""The 3D motion editor in a kernel (the browser test drags it in JupyterLab): the views map
metres to canvas pixels and back, picking finds the nearest handle, mouse events on a handle
move the trajectory (top view: x, z; side view: z, y) or a keypose joint by the dragged metres,
Regenerate with the shipped generator follows the dragged pelvis, the condition switches, Undo
and Reset, Save, and bad input shows a readable message."""
from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("ipycanvas")

from physlab.motion.editing import drag_trajectory, move_joint  # noqa: E402
from physlab.motion.skeleton import joint_index  # noqa: E402
from physlab.viz.motion_editor import (MotionEditor, View, condition_errors,  # noqa: E402
                                       fit_views, handle_indices, pick, tick_step, view_at)

PELVIS_Y = 0.9


def _walk():
    """A synthetic 40-frame walk along +z (5 cm a frame): a fixed body around the pelvis."""
    rng = np.random.default_rng(0)
    body = rng.uniform(-0.25, 0.25, size=(22, 3))
    body[:, 1] = np.linspace(0.0, 0.8, 22) - 0.45          # feet below the pelvis, head above
    body[0] = 0.0
    pelvis = np.stack([np.zeros(40), np.full(40, PELVIS_Y), 0.05 * np.arange(40)], axis=1)
    return pelvis[:, None, :] + body[None]                  # (40, 22, 3)


class FakeGenerator:
    """Records its calls; returns the walk moved so its pelvis follows the given pelvis path
    (and the first frame is the keypose when given)."""

    def __init__(self):
        self.calls = []

    def __call__(self, action, seed=0, keypose_3d=None, keypose_at="first",
                 trajectories_3d=None, **options):
        self.calls.append(dict(action=action, seed=seed, keypose_3d=keypose_3d,
                               keypose_at=keypose_at, trajectories_3d=trajectories_3d,
                               **options))
        x = _walk() + 0.001 * seed
        if trajectories_3d and "pelvis" in trajectories_3d:
            x += (trajectories_3d["pelvis"] - x[:, 0])[:, None]
        if keypose_3d is not None:
            x[0] = keypose_3d
        return x


@pytest.fixture(scope="module")
def shipped():
    """The shipped generator and its 20-step walk (seed 0)."""
    pytest.importorskip("torch")
    from physlab.motion import generate

    return generate, generate("a person walks", seed=0, steps=20)


def _mouse(ed, points):
    """Mouse down at the first canvas pixel, moves through the rest, up at the last (through
    the error guard, as the canvas delivers them)."""
    P = np.asarray(points, float).reshape(-1, 2)
    ed._guard(ed._on_down, *P[0])
    for p in P[1:]:
        ed._guard(ed._on_move, *p)
    ed._guard(ed._on_up, *P[-1])


def _drag_px(ed, view, point, d_px, steps=4):
    """Drag from the canvas pixel of world ``point`` in ``view`` by ``d_px`` canvas px."""
    p0 = ed.views[view].to_canvas(point)
    _mouse(ed, [p0 + k / steps * np.asarray(d_px, float) for k in range(steps + 1)])


# ---------------------------------------------------------------------------- pure functions
def test_view_maps_metres_to_pixels_and_back():
    top = View("top", (0, 2), (10, 20, 200, 100), (0.5, 1.0), 50.0)
    np.testing.assert_allclose(top.to_canvas([0.5, 7.0, 1.0]), [110, 70])  # centre; y ignored
    np.testing.assert_allclose(top.to_canvas([1.5, 0.0, 1.0]), [160, 70])  # +1 m x: right
    np.testing.assert_allclose(top.to_canvas([0.5, 0.0, 2.0]), [110, 20])  # +1 m z: up (y down)
    side = View("side", (2, 1), (0, 0, 100, 100), (0.0, 0.0), 10.0)
    np.testing.assert_allclose(side.to_canvas([[9, 1, 2], [0, -1, 0]]), [[70, 40], [50, 60]])
    P = np.random.default_rng(1).normal(size=(5, 3))
    for v in (top, side):                                   # to_metres inverts to_canvas
        back = np.array([v.to_metres(*q) for q in v.to_canvas(P)])
        np.testing.assert_allclose(back, P[:, list(v.axes)], atol=1e-12)
    assert top.bounds() == ((-1.5, 2.5), (0.0, 2.0))
    assert top.contains(10, 20) and not top.contains(9, 20) and top.contains(9, 20, pad=1)


def test_fit_views_shows_everything_at_one_scale():
    P = np.array([[-0.2, 0.0, 0.0], [0.2, 1.7, 2.0]])
    views = fit_views(P, size=(760, 440), margin=0.3)
    top, side = views["top"], views["side"]
    # plot height 440 - 26 - 36 = 378 px over the z range 2.6 m (the tightest constraint)
    assert top.scale == side.scale == pytest.approx(378 / 2.6)
    assert top.rect[2] == 150 and top.rect[0] + top.rect[2] < side.rect[0]
    assert side.rect[0] + side.rect[2] <= 760 and top.rect[1] + top.rect[3] <= 440
    for v in views.values():
        (r0, r1), (u0, u1) = v.bounds()
        a, b = v.axes
        assert r0 <= P[:, a].min() - 0.3 + 1e-9 and P[:, a].max() + 0.3 <= r1 + 1e-9
        assert u0 <= P[:, b].min() and P[:, b].max() <= u1
    assert side.bounds()[1][0] <= -0.1                      # the floor is in the side view
    assert view_at(views, *top.to_canvas(P[0])) == "top"
    assert view_at(views, *side.to_canvas(P[1])) == "side"
    assert view_at(views, top.rect[0] + top.rect[2] + 40, 100) is None   # between the panels
    with pytest.raises(ValueError, match="finite"):
        fit_views(np.full((2, 3), np.nan))


def test_pick_handles_and_ticks():
    px = np.array([[10.0, 10.0], [20.0, 10.0], [20.0, 10.0]])
    assert pick(px, 12, 11) == 0 and pick(px, 19, 10) == 1   # nearest; ties: the first
    assert pick(px, 40, 40) is None and pick(px, 40, 10, radius=25) == 1
    assert pick(np.zeros((0, 2)), 0, 0) is None
    assert handle_indices(40).tolist() == [0, 4, 8, 12, 16, 20, 24, 28, 32, 36, 39]
    assert handle_indices(9).tolist() == [0, 4, 8] and handle_indices(1).tolist() == [0]
    assert handle_indices(0).size == 0
    assert tick_step(150) == 0.5 and tick_step(500) == 0.1 and tick_step(20) == 5.0


def test_condition_errors_by_hand():
    x = _walk()
    key = x[-1] + [0.0, 0.0, 0.02]                          # every joint 2 cm off
    path = x[30:, 0] + [0.03, 0.04, 0.0]                    # 5 cm off over the last 10 frames
    e = condition_errors(x, {"keypose_at": "last", "keypose_3d": key,
                             "trajectories_3d": {"pelvis": path}})
    assert e == pytest.approx({"pelvis": 0.05, "keypose": 0.02})
    e = condition_errors(x, {"trajectories_3d": {"head": x[:, joint_index("head")]}})
    assert e == {"head": 0.0}                               # "first", no keypose: not listed


# ---------------------------------------------------------------------------- the widget
def test_default_clip_comes_from_generate():
    gen = FakeGenerator()
    ed = MotionEditor(action="a person runs", generate=gen, generate_options={"steps": 3})
    assert gen.calls == [dict(action="a person runs", seed=0, keypose_3d=None,
                              keypose_at="first", trajectories_3d=None, steps=3)]
    np.testing.assert_array_equal(ed.motion, _walk())
    c = ed.conditions
    assert set(c) == {"keypose_at", "keypose_3d", "trajectories_3d"}
    np.testing.assert_array_equal(c["keypose_3d"], _walk()[0])
    np.testing.assert_array_equal(c["trajectories_3d"]["pelvis"], _walk()[:, 0])
    c["trajectories_3d"]["pelvis"][:] = 0                   # a copy: the editor is untouched
    assert ed.conditions["trajectories_3d"]["pelvis"][5, 2] == 0.25
    assert ed.widget._dom_classes == ("physlab-motion-editor",)


def test_mouse_drag_moves_the_path_by_the_dragged_metres():
    ed = MotionEditor(joints=_walk(), generate=FakeGenerator())
    p = ed.conditions["trajectories_3d"]["pelvis"]
    s = ed.views["top"].scale
    _drag_px(ed, "top", p[20], (30.0, -15.0))               # right = +x, up the canvas = +z
    q = ed.conditions["trajectories_3d"]["pelvis"]
    np.testing.assert_allclose(q[20] - p[20], [30 / s, 0.0, 15 / s], atol=1e-9)
    np.testing.assert_allclose(q, drag_trajectory(p, 20, q[20], 6), atol=1e-12)  # falloff
    assert 0 < q[17, 0] - p[17, 0] < q[20, 0] - p[20, 0]
    np.testing.assert_allclose(q[:8], p[:8], atol=1e-3)       # far samples stay
    assert f"moved pelvis sample 20 by ({30 / s:+.2f}, +0.00, {15 / s:+.2f}) m" in ed.status
    assert ed._grab is None and len(ed._history) == 1       # one drag, one undo step

    ed.radius.value = 0                                      # side view: z right, y up
    _drag_px(ed, "side", q[39], (-20.0, -10.0))
    r = ed.conditions["trajectories_3d"]["pelvis"]
    np.testing.assert_allclose(r[39] - q[39], [0.0, 10 / s, -20 / s], atol=1e-9)
    np.testing.assert_allclose(r[:39], q[:39])               # radius 0: only that sample
    _mouse(ed, [ed.views["side"].to_canvas(q[20]) + [0, 60]])  # off every handle
    assert "nothing to grab here" in ed.status and len(ed._history) == 2
    x_gap = ed.views["top"].rect[0] + ed.views["top"].rect[2] + 40
    _mouse(ed, [(x_gap, 100)])                              # between the views: ignored
    assert len(ed._history) == 2


def test_regenerate_follows_the_dragged_pelvis(shipped):
    generate, clip = shipped
    ed = MotionEditor(joints=clip, generate=generate, generate_options={"steps": 20})
    p = ed.conditions["trajectories_3d"]["pelvis"]
    s = ed.views["top"].scale
    _drag_px(ed, "top", p[28], (0.4 * s, 0.0))             # 40 cm to the side (+x)
    q = ed.conditions["trajectories_3d"]["pelvis"]
    np.testing.assert_allclose(q[28] - p[28], [0.4, 0.0, 0.0], atol=1e-9)
    ed.regenerate_button.click()
    x = ed.motion
    assert "regenerated “a person walks” (seed 0)" in ed.status, ed.status
    assert np.linalg.norm(x[28, 0] - q[28]) < 0.05          # the pelvis follows the drag
    assert np.linalg.norm(x[:, 0] - q, axis=-1).mean() < 0.03
    assert np.linalg.norm(x[28, 0] - clip[28, 0]) > 0.3     # and really moved
    assert ed.errors == condition_errors(x, ed.conditions) and ed.errors["pelvis"] < 0.03
    assert f"pelvis {100 * ed.errors['pelvis']:.1f} cm" in ed.status
    assert f"keypose {100 * ed.errors['keypose']:.1f} cm" in ed.status
    ed.undo()                                                # back to the clip before
    np.testing.assert_array_equal(ed.motion, clip)
    np.testing.assert_allclose(ed.conditions["trajectories_3d"]["pelvis"], q)


def test_keypose_drag_and_switches():
    gen = FakeGenerator()
    ed = MotionEditor(joints=_walk(), generate=gen, generate_options={"steps": 7})
    k = ed.conditions["keypose_3d"]
    wrist = joint_index("left_wrist")
    s = ed.views["side"].scale
    ed.mode.value = "keypose"
    _drag_px(ed, "side", k[wrist], (0.0, -0.1 * s))          # 10 cm up
    k2 = ed.conditions["keypose_3d"]
    np.testing.assert_allclose(k2, move_joint(k, wrist, k[wrist] + [0, 0.1, 0]), atol=1e-9)
    assert "moved keypose left_wrist by (+0.00, +0.10, +0.00) m" in ed.status
    ed.seed.value = 3
    ed.regenerate()
    call = gen.calls[-1]
    assert call["seed"] == 3 and call["steps"] == 7 and call["keypose_at"] == "first"
    np.testing.assert_array_equal(call["keypose_3d"], k2)
    assert list(call["trajectories_3d"]) == ["pelvis"]
    assert ed.errors["keypose"] == 0.0

    ed.keypose.value = False                                 # off: not a condition
    assert "keypose_3d" not in ed.conditions and ed.mode.value == "trajectory"
    ed.mode.value = "keypose"
    _mouse(ed, [ed.views["side"].to_canvas(k[wrist])])
    assert "the keypose is off" in ed.status
    ed.keypose_at.value = "last"
    ed.keypose.value = True                                  # on again: read off the clip
    np.testing.assert_array_equal(ed.conditions["keypose_3d"], ed.motion[-1])
    ed.paths["left_foot"].value = True                       # a second path
    foot = joint_index("left_foot")
    np.testing.assert_array_equal(ed.conditions["trajectories_3d"]["left_foot"],
                                  ed.motion[:, foot])
    ed.paths["pelvis"].value = False
    assert list(ed.conditions["trajectories_3d"]) == ["left_foot"]
    ed.undo()                                                # pelvis back, box ticked
    assert ed.paths["pelvis"].value and set(ed.conditions["trajectories_3d"]) == {
        "pelvis", "left_foot"}
    ed.undo()                                                # left_foot off
    ed.undo()                                                # keypose off
    ed.undo()                                                # keypose at "first"
    assert not ed.keypose.value and ed.keypose_at.value == "first"
    assert "keypose_3d" not in ed.conditions and not ed.paths["left_foot"].value


def test_undo_and_reset():
    gen = FakeGenerator()
    ed = MotionEditor(joints=_walk(), generate=gen)
    ed.undo()
    assert "nothing to undo" in ed.status
    p = ed.conditions["trajectories_3d"]["pelvis"]
    ed.drag("pelvis", 36, p[36] + [1.5, 0.0, 0.0])          # far out: the views refit later
    ed.regenerate()
    moved = ed.motion.copy()
    assert np.allclose(moved[36, 0], p[36] + [1.5, 0, 0])
    before = ed.views
    ed.drag("pelvis", 12, p[12] + [0.0, 0.0, -0.2])
    ed.reset_button.click()
    assert "reset to the first clip" in ed.status
    np.testing.assert_array_equal(ed.motion, _walk())
    np.testing.assert_array_equal(ed.conditions["trajectories_3d"]["pelvis"], p)
    assert ed.views["top"].bounds()[0][1] < before["top"].bounds()[0][1]   # refit to the clip
    ed.undo_button.click()                                   # undo the reset
    np.testing.assert_array_equal(ed.motion, moved)
    assert ed.conditions["trajectories_3d"]["pelvis"][12, 2] == pytest.approx(p[12, 2] - 0.2)
    for _ in range(3):                                       # the drags and the regenerate
        ed.undo()
    np.testing.assert_array_equal(ed.motion, _walk())
    np.testing.assert_array_equal(ed.conditions["trajectories_3d"]["pelvis"], p)
    assert "undone (0 step(s) left" in ed.status


def test_save_writes_a_storyboard_frame(tmp_path):
    from physlab.motion.storyboard import StoryboardFrame

    ed = MotionEditor(joints=_walk(), generate=FakeGenerator(), action="a person jogs",
                      trajectory_joints=("pelvis", "head"))
    p = ed.conditions["trajectories_3d"]["pelvis"]
    ed.drag("pelvis", 8, p[8] + [0.25, 0.0, 0.0])
    path = tmp_path / "edit.json"
    ed.file.value = str(path)
    ed.save_button.click()
    assert f"saved the conditions (pelvis, head, keypose) to {path}" in ed.status
    data = json.loads(path.read_text())
    assert data["action"] == "a person jogs" and data["keypose_at"] == "first"
    np.testing.assert_allclose(data["trajectories_3d"]["pelvis"],
                               ed.conditions["trajectories_3d"]["pelvis"], atol=1e-5)
    frame = StoryboardFrame.from_dict(data, str(path))        # a storyboard reads it
    np.testing.assert_allclose(frame.trajectories_3d["pelvis"][8], p[8] + [0.25, 0, 0],
                               atol=1e-5)
    assert frame.action == "a person jogs"


def test_bad_input_gives_clear_messages():
    w = _walk()
    with pytest.raises(ValueError, match=r"\(T, 22, 3\) joints array"):
        MotionEditor(joints=w[:, :5])
    with pytest.raises(ValueError, match="40-frame clip, got 20"):
        MotionEditor(joints=w[:20])
    bad = w.copy()
    bad[3, 4, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        MotionEditor(joints=bad)
    with pytest.raises(ValueError, match="unknown names"):
        MotionEditor(joints=w, trajectory_joints=("nose",))
    with pytest.raises(TypeError, match="generate must be callable"):
        MotionEditor(joints=w, generate="physlab.motion.generate")
    with pytest.raises(TypeError, match="generate_options must be a dict"):
        MotionEditor(joints=w, generate_options=[("steps", 20)])
    with pytest.raises(ValueError, match="action must be a non-empty text"):
        MotionEditor(joints=w, action=" ")
    with pytest.raises(ValueError, match="keypose_at"):
        MotionEditor(joints=w, keypose_at="middle")
    assert list(MotionEditor(joints=w, trajectory_joints="head").conditions[
        "trajectories_3d"]) == ["head"]                      # one name is fine

    def broken(action, **kw):
        raise RuntimeError("checkpoint missing")

    ed = MotionEditor(joints=w, generate=broken)
    ed.regenerate_button.click()
    assert "RuntimeError: checkpoint missing" in ed.status and ed._history == []
    np.testing.assert_array_equal(ed.motion, w)
    ed = MotionEditor(joints=w, generate=lambda action, **kw: np.zeros((40, 21, 3)))
    ed.regenerate_button.click()
    assert "shape (40, 21, 3)" in ed.status and ed._history == []
    ed.action.value = ""
    ed.regenerate_button.click()
    assert "the action is empty" in ed.status
    ed._guard(ed.drag, "head", 3, [0, 1, 0])
    assert "'head' is not a trajectory condition; tick it first" in ed.status
    ed._guard(ed.drag, "pelvis", 40, [0, 1, 0])
    assert "index 40 is outside" in ed.status
    ed._guard(ed.move_keypose_joint, "left_wrist", [0, 1])
    assert "finite (3,) position" in ed.status and "Traceback" not in ed.status
    assert ed._history == []
