"""The storyboard editor in a kernel (the browser test presses its buttons in JupyterLab):
thumbnails; loading the example untouched round-trips it exactly; adding, moving and deleting
frames; drawing in a text-only frame (mouse events as the front end sends them) makes it a
sketch frame; errors show in the status line naming the frame; Generate (shipped generator,
fast options) shows the preview GIF and the timeline, Export writes files whose BVH reads
back with the animation's frame count."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("ipycanvas")

import imageio.v3 as iio  # noqa: E402

from physlab.motion.camera import Camera  # noqa: E402
from physlab.motion.sketch import Sketch, Stroke, template_pose  # noqa: E402
from physlab.motion.storyboard import Storyboard, StoryboardFrame  # noqa: E402
from physlab.viz.storyboard_editor import (PREVIEW_EVERY, PREVIEW_SIZE, THUMB_SIZE,  # noqa: E402
                                           StoryboardEditor, frame_thumbnail)
from physlab.viz.storyboard_view import EXPORT_FORMATS  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[2] / "data" / "motion" / "example_storyboard.json"
FAST = {"steps": 20, "guidance_final": 0}          # networks only, 20 DDIM steps: quick
HEAD = [(150 + 16 * np.cos(a), 110 + 16 * np.sin(a)) for a in np.linspace(0, 2 * np.pi, 25)]
FIGURE = [HEAD, [(150, 128), (150, 225)], [(110, 205), (150, 145), (190, 205)],
          [(150, 225), (132, 335)], [(150, 225), (168, 335)]]


def _png(b):
    assert b[:4] == b"\x89PNG"
    return iio.imread(b)


def _mouse(editor, points):
    """A stroke through ``points`` as the browser sends it: mouse events to the canvas's top
    layer, which dispatches them to the sketch canvas and the editor."""
    top = editor.canvas.canvas._canvases[-1]
    for k, (x, y) in enumerate(points):
        ev = "mouse_down" if k == 0 else "mouse_move"
        top._handle_frontend_event(None, {"event": ev, "x": float(x), "y": float(y)}, [])
    top._handle_frontend_event(None, {"event": "mouse_up", "x": float(points[-1][0]),
                                      "y": float(points[-1][1])}, [])


def _text(editor):
    return editor.status.split(">", 1)[1].rsplit("<", 1)[0]


def test_frame_thumbnail_draws_sketch_conditions_or_a_card():
    board = Storyboard.load(EXAMPLE)
    W, H = THUMB_SIZE
    sk = frame_thumbnail(board.frames[0], "1")
    assert sk.shape == (H, W, 3) and sk.dtype == np.uint8
    red = (sk[..., 0] > 180) & (sk[..., 1] < 90) & (sk[..., 2] < 90)
    black = sk.max(axis=2) < 60
    assert red.sum() > 20 and black.sum() > 20          # the trajectory and the figure
    card = frame_thumbnail(board.frames[1], "2")
    assert not ((card[..., 0] > 180) & (card[..., 1] < 90)).any()     # no red: text only
    body = card[20:-4, 4:-4].reshape(-1, 3)
    assert (np.abs(body.astype(int) - (247, 247, 242)).sum(axis=1) < 6).mean() > 0.8
    key3d = frame_thumbnail(StoryboardFrame("a person bows", keypose_3d=template_pose()), "3")
    assert (key3d[20:].max(axis=2) < 60).sum() > 20     # the projected keypose, in black
    sel = frame_thumbnail(board.frames[1], "2", selected=True)
    assert tuple(sel[H // 2, 0]) != tuple(card[H // 2, 0])      # a thick blue border
    assert sel[H // 2, 1, 2] > sel[H // 2, 1, 0] + 60
    with pytest.raises(TypeError, match="StoryboardFrame"):
        frame_thumbnail(board, "x")
    with pytest.raises(ValueError, match="at least"):
        frame_thumbnail(board.frames[0], size=(20, 20))


def test_loading_the_example_round_trips_it_untouched(tmp_path):
    e = StoryboardEditor(EXAMPLE, generate_options=FAST)
    assert [b.description for b in e.frame_buttons] == ["1: a person walks", "2: a person bows",
                                                       "3: a person…"]
    assert e.selected == 0 and e.frame_buttons[0].button_style == "info"
    assert e.canvas.sketch.size == (480, 400) and len(e.canvas.sketch.strokes) > 0
    assert (e.pitch.value, e.yaw.value) == (15.0, 30.0)
    assert e.storyboard.to_dict() == Storyboard.load(EXAMPLE).to_dict()
    e.file.value = str(tmp_path / "copy.json")
    e.save_button.click()
    assert "saved 3 frames" in e.status
    assert json.loads((tmp_path / "copy.json").read_text()) == json.loads(EXAMPLE.read_text())
    e.frame_buttons[1].click()                        # a text-only frame: an empty canvas
    assert e.selected == 1 and not e.canvas.sketch.strokes
    assert e.canvas.sketch.camera == Camera(pitch=15.0, yaw=30.0)        # the board's
    assert "text only" in e.frame_note.value and e.action.value == "a person bows"
    e.yaw.value = -20                                 # the board camera, for frames without one
    assert e.storyboard.camera == Camera(pitch=15.0, yaw=-20.0)
    assert e.storyboard.frames[0].camera == Camera(pitch=15.0, yaw=30.0)   # the sketch's own


def test_add_move_delete_frames():
    e = StoryboardEditor(Storyboard([StoryboardFrame("a person walks"),
                                     StoryboardFrame("a person jumps",
                                                     keypose_3d=template_pose())]))
    assert e.left_button.disabled and not e.right_button.disabled
    e.select(1)
    assert "conditions from the file (keypose_3d)" in e.frame_note.value
    before = e._slots[1][0].value
    e.yaw.value = 80                                  # 3D conditions seen by the board camera
    assert e._slots[1][0].value != before
    assert e.storyboard.frames[1].keypose_3d is not None      # kept while nothing is drawn
    e.frame_buttons[0].click()
    e.add_button.click()                              # after frame 1
    assert e.selected == 1 and len(e.frame_buttons) == 3 and "added frame 2" in e.status
    e.action.value = "a person sits down"
    assert e.frame_buttons[1].description.startswith("2: a person sits")
    e.right_button.click()
    assert e.selected == 2 and e.right_button.disabled
    assert [f.action for f in e.storyboard.frames] == ["a person walks", "a person jumps",
                                                        "a person sits down"]
    e.right_button.click()                            # already last: a message, no traceback
    assert "already the last" in e.status
    e.left_button.click()
    e.left_button.click()
    assert [f.action for f in e.storyboard.frames][0] == "a person sits down"
    e.delete_button.click()
    assert e.selected == 0 and [f.action for f in e.storyboard.frames] == ["a person walks",
                                                                           "a person jumps"]
    e.delete_button.click()
    e.delete_button.click()
    assert e.selected is None and not e.frame_buttons and e.canvas is None
    assert e.delete_button.disabled and e.action.disabled
    for button in (e.generate_button, e.save_button):
        button.click()
        assert "the storyboard is empty: press Add frame" in e.status
    e.add_button.click()
    assert len(e.storyboard) == 1 and e.storyboard.frames[0].sketch is None


def test_new_sketches_take_the_size_of_the_storyboards_sketches():
    sk = Sketch(size=(320, 240), strokes=[Stroke(np.array([[160.0, 120], [260, 120]]),
                                                 "trajectory")])
    e = StoryboardEditor(Storyboard([StoryboardFrame.from_sketch(sk),
                                     StoryboardFrame("a person bows")]))
    e.frame_buttons[1].click()
    assert e.canvas.sketch.size == (320, 240) and e.canvas.canvas.width == 320
    e.add_button.click()
    assert e.canvas.sketch.size == (320, 240)


def test_drawing_in_a_text_frame_makes_it_a_sketch_frame():
    e = StoryboardEditor(EXAMPLE)
    e.frame_buttons[1].click()
    before = e._slots[1][0].value
    for stroke in FIGURE:
        _mouse(e, stroke)
    assert len(e.canvas.sketch.strokes) == 5
    assert e._slots[1][0].value != before             # the thumbnail follows the drawing
    assert "drawn" in e.frame_note.value
    e.keypose_at.value = "last"                       # no trajectory strokes: the dropdown
    f = e.storyboard.frames[1]
    assert f.sketch is e.canvas.sketch and f.keypose_2d.shape == (22, 2)
    assert f.camera == Camera(pitch=15.0, yaw=30.0) and f.keypose_at == "last"
    assert f.action == "a person bows" and e.canvas.sketch.action == "a person bows"
    e.canvas.mode.value = "trajectory"
    p0 = e.canvas.sketch.joints[0]
    _mouse(e, [(p0[0] + 8 * k, p0[1]) for k in range(20)])  # from the pelvis: keypose first
    f = e.storyboard.frames[1]
    assert set(f.trajectories_2d) == {"pelvis"} and f.keypose_at == "first"
    assert e.keypose_at.value == "first" and e.keypose_at.disabled     # the strokes decide
    e.frame_buttons[0].click()                        # the drawing stays with frame 2
    e.frame_buttons[1].click()
    assert len(e.canvas.sketch.strokes) == 6
    e.canvas.clear.click()                            # cleared: text-only again
    f = e.storyboard.frames[1]
    assert f.sketch is None and not f.has_2d and "text only" in e.frame_note.value
    assert not e.keypose_at.disabled


def test_errors_show_in_the_status_line_naming_the_frame(tmp_path):
    e = StoryboardEditor(EXAMPLE)
    e.frame_buttons[2].click()
    e.action.value = "   "
    e.generate_button.click()                         # no traceback: the status line
    assert _text(e).startswith("ValueError: frame 3 (") and "action must be" in e.status
    e.action.value = "a person waves the right hand"
    e.frame_buttons[0].click()
    p0 = e.canvas.sketch.joints[0]                    # a second stroke from the pelvis
    e.canvas.add_stroke(p0 + np.array([[0.0, 0], [-40, -60]]), "trajectory")
    e.file.value = str(tmp_path / "never_written.json")
    e.save_button.click()
    assert "frame 1 ('a person walks')" in e.status
    assert "two trajectory strokes" in e.status and not (tmp_path / "never_written.json").exists()
    e.canvas.undo.click()
    bad = tmp_path / "bad.json"
    bad.write_text('{"version": 1, "frames": [')
    e.file.value = str(bad)
    e.load_button.click()
    assert "not valid JSON" in e.status and len(e.frame_buttons) == 3   # nothing replaced
    d = json.loads(EXAMPLE.read_text())
    d["frames"][1]["keypose_3d"] = [[0.0, 0.0]] * 22                 # wrong shape in frame 2
    bad.write_text(json.dumps(d))
    e.load_button.click()
    assert "frame 2" in e.status and "keypose_3d must have shape (k, 3)" in e.status
    e.file.value = str(tmp_path / "missing.json")
    e.load_button.click()
    assert "FileNotFoundError" in e.status
    e.export_button.click()
    assert "nothing to export yet: press Generate first" in e.status
    e.frame_buttons[0].click()
    e.canvas.add_stroke(np.array([[10.0, 10], [20, 20]]), "pose")     # a scribble, no figure
    e.canvas.clear.click()
    assert e.storyboard.frames[0].sketch is None


def test_generate_options_reach_animate_storyboard(monkeypatch):
    import physlab.motion.storyboard as storyboard

    seen = {}

    def fake(sb, **kw):
        seen.update(kw, frames=len(sb))
        raise ValueError("frames[1] ('a person bows'): stand-in stops here")

    monkeypatch.setattr(storyboard, "animate_storyboard", fake)
    e = StoryboardEditor(EXAMPLE, generate_options={"steps": 7, "guidance_final": 0})
    e.transition.value, e.seed.value, e.method.value = 0, 5, "slerp"
    e.generate_button.click()
    assert seen == {"transition": 20, "seed": 5, "progress": True, "method": "concat",
                    "steps": 7, "guidance_final": 0, "frames": 3}     # 0 frames = a plain cut
    assert "ValueError: frame 2 ('a person bows'): stand-in" in e.status
    e.transition.value = 12
    e.generate_button.click()
    assert seen["method"] == "slerp" and seen["transition"] == 12
    assert e.animation is None and e.preview.layout.display == "none"
    with pytest.raises(ValueError, match=r"must not set \['seed'\]"):
        StoryboardEditor(EXAMPLE, generate_options={"seed": 3})


@pytest.mark.slow
def test_generate_preview_and_export(tmp_path):
    from physlab.viz.storyboard_view import check_bvh

    e = StoryboardEditor(EXAMPLE, generate_options=FAST, export_dir=str(tmp_path / "out"))
    e.transition.value, e.method.value = 10, "linear"
    e.generate_button.click()
    assert _text(e).startswith("generated 140 frames"), e.status   # 3 × 40 + 2 × 10
    anim = e.animation
    assert anim.joints.shape == (140, 22, 3) and e.animated.to_dict() == e.storyboard.to_dict()
    gif = e.preview.value
    assert gif[:4] == b"GIF8" and e.preview.layout.display is None
    frames = iio.imread(gif, index=None)
    assert frames.shape[:3] == (140 // PREVIEW_EVERY, PREVIEW_SIZE[1], 2 * PREVIEW_SIZE[0])
    assert "<b>3</b> a person waves the right hand 5.00–7.00 s" in e.timeline.value
    assert e.export_formats == EXPORT_FORMATS         # all by default (the browser test)
    e.export_formats = ("bvh", "sketch_gif", "json")  # not the capsule renders: quicker
    e.export_button.click()
    assert _text(e).startswith("exported 3 files (140 frames)"), e.status
    assert list(e.exported) == ["bvh", "sketch_gif", "json"]
    assert all(p.is_file() and p.parent == tmp_path / "out" for p in e.exported.values())
    assert "storyboard.bvh" in e.files.value
    assert check_bvh(e.exported["bvh"], n_frames=140)["n_frames"] == 140
    assert Storyboard.load(e.exported["json"]).to_dict() == Storyboard.load(EXAMPLE).to_dict()
    e.frame_buttons[1].click()
    e.action.value = "a person jumps"                 # edited after Generate
    e.export_dir.value = str(tmp_path / "again")
    e.export_formats = ("json",)
    e.export_button.click()
    assert "changed since Generate" in e.status
    assert Storyboard.load(e.exported["json"]).frames[1].action == "a person bows"


def test_strokes_drawn_after_generate_are_not_exported(tmp_path):
    """The canvas edits the frame's Sketch in place: the editor exports a copy of what it
    generated, not the drawing as it is now."""
    e = StoryboardEditor(EXAMPLE, generate_options=FAST, export_dir=str(tmp_path / "out"))
    e.frame_buttons[0].click()
    wrists = e.canvas.sketch.joints[[20, 21]]
    e.canvas.add_stroke(wrists[0] + np.array([[0.0, 0.0], [20.0, -5.0], [40.0, -10.0]]),
                        "trajectory")                          # edited: a fresh frame
    n_strokes = len(e.canvas.sketch.strokes)
    e.generate_button.click()
    assert _text(e).startswith("generated"), e.status
    e.canvas.add_stroke(wrists[1] + np.array([[0.0, 0.0], [-30.0, 0.0]]), "trajectory")
    e.export_formats = ("json",)
    e.export_button.click()
    assert "changed since Generate" in e.status
    assert len(Storyboard.load(e.exported["json"]).frames[0].sketch.strokes) == n_strokes
