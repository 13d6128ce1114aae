"""Tests of physlab.motion.storyboard: frames and their validation, the JSON round trip
(with a drawn sketch), and a three-frame storyboard to one animation with the shipped
generator (shape, segments, determinism, no visible seam compared with a plain cut)."""
import json
from pathlib import Path

import numpy as np
import pytest
import torch

from physlab.motion import (Storyboard, StoryboardFrame, animate_storyboard,
                            storyboard_to_motion)
from physlab.motion.blend import junction_acceleration_ratio, junction_step_ratio
from physlab.motion.camera import Camera
from physlab.motion.metrics import bone_length_variation, floor_penetration
from physlab.motion.sketch import Sketch, template_pose

SKETCH = Path(__file__).resolve().parents[2] / "data" / "motion" / "example_sketch.json"
FAST = dict(steps=20, guidance_final=0)          # networks only, 20 DDIM steps: quick


def _board():
    key = template_pose()
    return Storyboard([StoryboardFrame("a person walks"),
                       StoryboardFrame("a person bows", keypose_3d=key),
                       StoryboardFrame("a person waves with the right hand")],
                      title="walk, bow, wave")


def test_frame_validation_names_the_field():
    with pytest.raises(ValueError, match="action"):
        StoryboardFrame("  ")
    with pytest.raises(ValueError, match="keypose_at"):
        StoryboardFrame("a person walks", keypose_at="middle")
    with pytest.raises(ValueError, match=r"keypose_3d must have shape \(22, 3\)"):
        StoryboardFrame("a person walks", keypose_3d=np.zeros((21, 3)))
    with pytest.raises(ValueError, match="unknown joint names"):
        StoryboardFrame("a person walks", trajectories_3d={"nose": np.zeros((5, 3))})
    with pytest.raises(ValueError, match="not both"):
        StoryboardFrame("a person walks", keypose_2d=np.zeros((22, 2)),
                        keypose_3d=template_pose(), camera=Camera())
    # a drawn frame may take its camera from the storyboard, but needs one from somewhere
    drawn = StoryboardFrame("a person walks", keypose_2d=np.zeros((22, 2)))
    assert Storyboard([drawn], camera=Camera(yaw=30)).frames[0].camera is None
    assert drawn.generate_kwargs(Camera(yaw=30))["camera"] == Camera(yaw=30)
    with pytest.raises(ValueError, match=r"frames\[0\] \('a person walks'\): .*need the camera"):
        Storyboard([drawn])
    with pytest.raises(TypeError, match=r"frames\[1\] must be a StoryboardFrame"):
        Storyboard([StoryboardFrame("a person walks"), "not a frame"])
    with pytest.raises(ValueError, match="at least one frame"):
        Storyboard([])


def test_json_round_trip_with_a_sketch(tmp_path):
    sk = Sketch.load(SKETCH)
    frame = StoryboardFrame.from_sketch(sk)
    assert frame.camera == sk.camera and frame.sketch is sk and frame.has_2d
    board = Storyboard([frame, StoryboardFrame("a person bows", keypose_3d=template_pose(),
                                               keypose_at="last")],
                       camera=Camera(pitch=20, yaw=30), title="demo")
    path = board.save(tmp_path / "board.json")
    back = Storyboard.load(path)
    assert back.title == "demo" and back.camera == board.camera and len(back) == 2
    for f, g in zip(board.frames, back.frames):
        assert f.action == g.action and f.keypose_at == g.keypose_at
        for k in ("keypose_2d", "keypose_3d"):
            assert (getattr(f, k) is None) == (getattr(g, k) is None)
            if getattr(f, k) is not None:
                assert np.allclose(getattr(f, k), getattr(g, k), atol=1e-5)
    assert back.frames[0].sketch.to_dict() == sk.to_dict()
    assert set(back.frames[0].trajectories_2d) == set(frame.trajectories_2d or {})


def test_load_errors_name_the_file_and_frame(tmp_path):
    p = tmp_path / "b.json"
    p.write_text("{not json")
    with pytest.raises(ValueError, match="b.json: not valid JSON"):
        Storyboard.load(p)
    p.write_text(json.dumps({"version": 1, "frames": [{"action": "a person walks"},
                                                      {"action": "x", "pose": 1}]}))
    with pytest.raises(ValueError, match=r"frames\[1\]: unknown keys \['pose'\]"):
        Storyboard.load(p)
    p.write_text(json.dumps({"version": 7, "frames": []}))
    with pytest.raises(ValueError, match="'version' must be 1"):
        Storyboard.load(p)
    # a failed write keeps the previous file
    good = _board().save(tmp_path / "keep.json")
    before = good.read_text()
    with pytest.raises(TypeError):
        Storyboard([StoryboardFrame("a person walks", keypose_3d=np.zeros((22, 3)))],
                   title=object()).save(good)
    assert good.read_text() == before


@pytest.fixture(scope="module")
def animation():
    torch.set_num_threads(1)
    return animate_storyboard(_board(), transition=20, seed=3, **FAST)


def test_three_frames_become_one_animation(animation):
    a = animation
    assert a.joints.shape == (3 * 40 + 2 * 20, 22, 3)
    assert [s.stop - s.start for s in a.segments] == [40, 40, 40]
    assert [t.stop - t.start for t in a.transitions] == [20, 20]
    assert a.segments[1].start == a.transitions[0].stop
    assert a.frame_at(0) == 0 and a.frame_at(a.segments[2].start) == 2
    assert len(a.seconds["generate"]) == 3 and len(a.seconds["blend"]) == 2
    # the bow starts in its keypose (networks only here: the pose within 3 cm, as issue 12's
    # keypose error, under the pelvis; placed 12 cm off, measured 2026-11-26)
    key = _board().frames[1].keypose_3d
    c = a.clips[1][0]
    assert np.linalg.norm((c - c[:1]) - (key - key[:1]), axis=-1).mean() < 0.06
    assert np.linalg.norm(c - key, axis=-1).mean() < 0.15
    for w in a.windows:
        assert bone_length_variation(a.joints[w]) < 0.01
        assert floor_penetration(a.joints[w]) <= 0.01
    # placements map each clip onto its segment (outside the blending windows exactly)
    for i in range(3):
        loc = a.local(i)
        keep = np.ones(40, bool)
        if i > 0:
            keep[:10] = False
        if i < 2:
            keep[-10:] = False
        assert np.allclose(loc[keep], a.clips[i][keep], atol=1e-9)
    # deterministic, and storyboard_to_motion returns the same joints
    again = storyboard_to_motion(_board(), transition=20, seed=3, **FAST)
    assert np.array_equal(again, a.joints)


def test_example_storyboard_has_no_visible_seam():
    """The shipped example (drawn walk, bow, wave) with the default blending: one skeleton
    throughout, feet above the floor, and no seam — no junction changes velocity more than the
    clips do next to it (acceleration ratio <= 2; measured 0.64-0.97 walk -> bow and
    0.85-1.19 bow -> wave over seeds 0-3, a plain cut 4-85, linear blends 2.4-4.1 at the
    bow -> wave kinks; scripts/storyboard_seams.py, 2026-11-28). Walk -> bow also moves no
    faster than the clips there (step ratio, 'local', 0.83-0.89 <= 1.5). Bow -> wave need not:
    the bow ends still with the hands down and the wave starts with the right hand up, so the
    join may raise the hand faster than either clip moves (1.31-2.20; 1.9-3.5 with older
    models)."""
    board = Storyboard.load(Path(__file__).resolve().parents[2] / "data" / "motion" /
                            "example_storyboard.json")
    a = animate_storyboard(board, seed=0, steps=20)
    assert bone_length_variation(a.joints) < 1e-3
    assert floor_penetration(a.joints) <= 0.01
    for k in range(2):
        assert junction_acceleration_ratio(a.joints, a.windows[k], a.clips[k:k + 2]) <= 2.0
    assert junction_step_ratio(a.joints, a.windows[0], a.clips[:2], "local") <= 1.5


def test_blending_beats_a_plain_cut(animation):
    cut = animate_storyboard(_board(), seed=3, method="concat", **FAST)
    assert cut.joints.shape == (120, 22, 3)
    for k in range(2):
        pair = [animation.clips[k], animation.clips[k + 1]]
        r_blend = junction_step_ratio(animation.joints, animation.windows[k], pair)
        r_cut = junction_step_ratio(cut.joints, cut.windows[k], pair)
        assert r_blend < r_cut, (k, r_blend, r_cut)


def test_animate_errors(tmp_path):
    board = _board()
    board.frames.append("not a frame")                   # edited after construction
    with pytest.raises(TypeError, match=r"frames\[3\]"):
        animate_storyboard(board)
    with pytest.raises(ValueError, match="blend_options may not set"):
        animate_storyboard(_board(), blend_options={"seed": 1})
    with pytest.raises(TypeError, match="title"):
        Storyboard([StoryboardFrame("a person walks")], title=None)
    with pytest.raises(ValueError, match=r"trajectories_3d\['pelvis'\] must be"):
        StoryboardFrame("a person walks", trajectories_3d={"pelvis": None})
    with pytest.raises(TypeError, match="Storyboard"):
        animate_storyboard([StoryboardFrame("a person walks")])
    with pytest.raises(ValueError, match="method"):
        animate_storyboard(_board(), method="morph")
    with pytest.raises(ValueError, match="seed"):
        animate_storyboard(_board(), seed=-1)


def test_frame_at_range_and_bad_transitions_fail_before_generating(animation, monkeypatch):
    """frame_at refuses frames outside the animation; a transition the method cannot take
    is an error before any clip is generated (the generator is never called)."""
    n = len(animation.joints)
    assert animation.frame_at(n - 1) == 2
    for k in (-1, n, 2.0, True):
        with pytest.raises(IndexError, match=f"animation frame {k!r} out of range"):
            animation.frame_at(k)
    import physlab.motion.sampling as sampling

    def refuse(*_a, **_k):
        raise AssertionError("the generator was loaded")
    monkeypatch.setattr(sampling, "load_generator", refuse)
    with pytest.raises(ValueError, match=r"transition must be an integer number of frames in "
                                         r"0\.\.38, got 39"):
        animate_storyboard(_board(), transition=39)
    with pytest.raises(ValueError, match="transition must be >= 1 frame for method 'linear'"):
        animate_storyboard(_board(), transition=0, method="linear")


def test_one_frame_own_skeletons_and_blend_options():
    """A one-frame storyboard is its clip; common_skeleton=False keeps each clip's own bones
    (the clips outside the windows are the generated ones); blend_options reach blend()."""
    one = animate_storyboard(Storyboard([StoryboardFrame("a person bows")]), seed=5, **FAST)
    assert one.joints.shape == (40, 22, 3) and one.windows == [] and one.transitions == []
    assert np.array_equal(one.joints, one.clips[0])
    own = animate_storyboard(_board(), seed=3, common_skeleton=False, method="linear", **FAST)
    same = animate_storyboard(_board(), seed=3, method="linear", **FAST)
    from physlab.motion.body import clip_bone_lengths

    l0, l1 = clip_bone_lengths(own.clips[0]), clip_bone_lengths(own.clips[1])
    assert np.abs(l0 - l1).max() > 1e-3                   # generated clips: own bones
    assert np.allclose(clip_bone_lengths(same.clips[0]), clip_bone_lengths(same.clips[1]))
    a = animate_storyboard(_board(), seed=3, blend_options={"guidance": (0, 0)}, **FAST)
    b = animate_storyboard(_board(), seed=3, **FAST)
    assert not np.allclose(a.joints[a.windows[0]], b.joints[b.windows[0]])
    assert np.array_equal(a.joints[:a.windows[0].start], b.joints[:b.windows[0].start])
