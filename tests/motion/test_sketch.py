"""Sketches: the template, joints snapped from stick-figure strokes (against the real pose the
figure was drawn from), strokes -> trajectories (attachment, first/last, arc-length and
drawing-speed resampling), pixels -> normalised units, JSON and PNG input, bad input."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from physlab.motion.camera import Camera, from_pixels, to_pixels
from physlab.motion.sketch import (Sketch, Stroke, TemplateSnapper, attach_trajectories,
                                   keypose_from_strokes, resample_stroke, sketch_from_png,
                                   template_pose)
from physlab.motion.skeleton import JOINT_NAMES, PARENTS, bone_lengths

LESSON_WINDOWS = Path(__file__).resolve().parents[2] / "data" / "motion" / "lesson_windows.npz"
ORIGIN, PPU = (240.0, 420.0), 200.0
VIEWS = [Camera(1, 0, 0), Camera(1, 20, 30), Camera(1, 10, -40)]


def _idx(*names):
    return [JOINT_NAMES.index(n) for n in names]


def _real_pose(k=2):
    x = np.load(LESSON_WINDOWS)["held_out"][k, 0]
    return x - [x[0, 0], 0.0, x[0, 2]]


def _stick_figure(px, one_line_arms=False):
    """The strokes a person would draw over 2D joints: head circle, body line, limbs."""
    head = px[15]
    a = np.linspace(0, 2 * np.pi, 30)
    strokes = [Stroke(head + 0.1 * PPU * np.c_[np.cos(a), np.sin(a)]),
               Stroke(px[_idx("neck", "spine3", "spine2", "spine1", "pelvis")])]
    if one_line_arms:
        strokes.append(Stroke(px[_idx("left_wrist", "left_elbow", "left_shoulder", "neck",
                                      "right_shoulder", "right_elbow", "right_wrist")]))
    else:
        strokes += [Stroke(px[_idx(f"{s}_shoulder", f"{s}_elbow", f"{s}_wrist")])
                    for s in ("left", "right")]
    strokes += [Stroke(px[_idx(f"{s}_hip", f"{s}_knee", f"{s}_ankle", f"{s}_foot")])
                for s in ("left", "right")]
    return strokes


def test_template_is_a_standing_body_with_the_data_bone_lengths():
    x = template_pose()
    assert x.shape == (22, 3)
    assert x[:, 1].min() == pytest.approx(0.0)
    real = np.median(bone_lengths(np.load(LESSON_WINDOWS)["held_out"].reshape(-1, 22, 3)), 0)
    np.testing.assert_allclose(bone_lengths(x[None])[0], real, rtol=0.05)  # its source
    assert x[_idx("left_wrist"), 0] > 0 > x[_idx("right_wrist"), 0]      # left = +x
    assert np.all(x[_idx("left_foot", "right_foot"), 2] > x[_idx("left_ankle", "right_ankle"), 2])


@pytest.mark.parametrize("cam", VIEWS, ids=str)
@pytest.mark.parametrize("one_line_arms", [False, True])
def test_snapped_joints_land_on_the_pose_the_figure_was_drawn_from(cam, one_line_arms):
    px = to_pixels(cam.project(_real_pose()), ORIGIN, PPU)
    j = keypose_from_strokes(_stick_figure(px, one_line_arms), cam)
    err = np.linalg.norm(j - px, axis=1)
    height = np.ptp(px[:, 1])
    assert err.mean() < 0.04 * height and err.max() < 0.12 * height, (err.mean(), err.max())
    for side, other in (("left", "right"), ("right", "left")):           # sides not swapped
        w, o = _idx(f"{side}_wrist")[0], _idx(f"{other}_wrist")[0]
        assert np.linalg.norm(j[w] - px[w]) < np.linalg.norm(j[w] - px[o])
    assert TemplateSnapper()(_stick_figure(px), cam).shape == (22, 2)


def test_missing_limbs_come_from_the_template_and_bad_input_is_named():
    cam = Camera()
    px = to_pixels(cam.project(template_pose()), ORIGIN, PPU)
    strokes = _stick_figure(px)[:2]                                        # head and body only
    j = keypose_from_strokes(strokes, cam)
    assert np.all(np.isfinite(j))
    b = np.linalg.norm(j[1:] - j[PARENTS[1:]], axis=1)
    ref = np.linalg.norm(px[1:] - px[PARENTS[1:]], axis=1)
    np.testing.assert_allclose(b, ref, rtol=0.05, atol=1.0)               # template limbs
    with pytest.raises(ValueError, match="no pose strokes"):
        keypose_from_strokes([Stroke(px[:3], "trajectory")], cam)
    with pytest.raises(TypeError, match="camera must be"):
        keypose_from_strokes(strokes, "front")
    with pytest.raises(ValueError, match="kind must be one of"):
        Stroke(px[:3], "arrow")
    with pytest.raises(ValueError, match=r"shape \(n, 2\)"):
        Stroke(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="non-decreasing"):
        Stroke(px[:3], times=[0.0, 0.2, 0.1])


def test_resampling_by_arc_length_and_by_drawing_time():
    p = np.c_[np.linspace(0, 1, 11) ** 2 * 100, np.zeros(11)]             # uneven samples
    r = resample_stroke(p, 5)
    np.testing.assert_allclose(r[:, 0], [0, 25, 50, 75, 100])
    t = np.linspace(0, 1, 11)                       # drawn with x = 100 t^2: slow, then fast
    r = resample_stroke(p, 5, times=t)
    np.testing.assert_allclose(r[:, 0], 100 * np.linspace(0, 1, 5) ** 2, atol=0.5)
    np.testing.assert_array_equal(resample_stroke(p[:1], 3), np.repeat(p[:1], 3, 0))
    with pytest.raises(ValueError, match="n must be an integer"):
        resample_stroke(p, 0)


def test_trajectory_strokes_attach_by_their_start_or_end():
    j = to_pixels(Camera().project(template_pose()), ORIGIN, PPU)
    wrist, pelvis = j[_idx("right_wrist")[0]], j[0]
    away = Stroke(wrist + np.c_[np.linspace(0, -80, 9), np.linspace(0, -60, 9)], "trajectory")
    trajs, at = attach_trajectories([away], j, frames=10)
    assert list(trajs) == ["right_wrist"] and at == "first" and trajs["right_wrist"].shape == (10, 2)
    np.testing.assert_allclose(trajs["right_wrist"][0], wrist)
    into = Stroke(pelvis + np.c_[np.linspace(-150, 0, 9), np.zeros(9)], "trajectory")
    trajs, at = attach_trajectories([into], j)
    assert list(trajs) == ["pelvis"] and at == "last"
    np.testing.assert_allclose(trajs["pelvis"][-1], pelvis)
    trajs, at = attach_trajectories([into, away], j)           # the second one is read backwards
    assert at == "last" and np.allclose(trajs["right_wrist"][-1], wrist)
    with pytest.raises(ValueError, match="two trajectory strokes"):
        attach_trajectories([away, away], j)
    with pytest.raises(ValueError, match="frames must be"):
        attach_trajectories([away], j, frames=41)


def test_conditions_are_the_projection_of_the_figure_in_normalised_units():
    """A figure drawn exactly as the template seen by the camera, pelvis anywhere on the
    canvas: keypose_2d must come out as the camera's projection of the template placed at
    the canonical origin (the scale recovered from the drawn bones)."""
    cam = Camera(1.0, 15, 25)
    uv = cam.project(template_pose())
    px = to_pixels(uv, (300.0, 350.0), 150.0)
    sk = Sketch(action="a person waves the right hand", camera=cam, strokes=_stick_figure(px),
                joints=px)
    walk = Stroke(px[0] + np.c_[np.linspace(0, 120, 20), np.zeros(20)], "trajectory")
    sk.strokes.append(walk)
    c = sk.conditions()
    assert c["keypose_at"] == "first" and c["camera"] is cam
    np.testing.assert_allclose(c["keypose_2d"], uv, atol=1e-6)
    np.testing.assert_allclose(c["trajectories_2d"]["pelvis"][-1] - c["trajectories_2d"]["pelvis"][0],
                               [120 / 150.0, 0.0], atol=1e-9)
    origin, ppu = sk.pixel_frame()
    np.testing.assert_allclose(from_pixels(px, origin, ppu), uv, atol=1e-6)
    with pytest.raises(ValueError, match="the sketch is empty"):
        Sketch().conditions()


def test_json_round_trip_and_errors(tmp_path):
    cam = Camera(1.1, 10, -20)
    px = to_pixels(cam.project(_real_pose()), ORIGIN, PPU)
    sk = Sketch(action="a person kicks", camera=cam, strokes=_stick_figure(px), size=(400, 500))
    sk.strokes.append(Stroke(px[:4], "trajectory", times=[0, 0.1, 0.2, 0.4]))
    sk.keypose()
    path = tmp_path / "s.json"
    sk.save(path)
    back = Sketch.load(path)
    assert back.action == sk.action and back.camera == cam and back.size == (400, 500)
    assert [s.kind for s in back.strokes] == [s.kind for s in sk.strokes]
    np.testing.assert_allclose(back.joints, sk.joints, atol=0.01)
    np.testing.assert_allclose(back.strokes[-1].times, [0, 0.1, 0.2, 0.4])
    d = json.loads(path.read_text())
    d["strokes"][2]["points"] = [[1, 2, 3]]
    (tmp_path / "bad.json").write_text(json.dumps(d))
    with pytest.raises(ValueError, match=r"bad\.json: strokes\[2\]"):
        Sketch.load(tmp_path / "bad.json")
    (tmp_path / "v.json").write_text(json.dumps({**d, "version": 9}))
    with pytest.raises(ValueError, match="'version' must be 1"):
        Sketch.load(tmp_path / "v.json")
    (tmp_path / "t.json").write_text("{")
    with pytest.raises(ValueError, match="not valid JSON"):
        Sketch.load(tmp_path / "t.json")


def _draw_png(path, px, traj_px, size=(480, 480)):
    import imageio.v3 as iio
    from skimage.draw import circle_perimeter, line

    img = np.full((size[1], size[0], 3), 255, np.uint8)

    def poly(points, color):
        for a, b in zip(points[:-1], points[1:]):
            rr, cc = line(int(a[1]), int(a[0]), int(b[1]), int(b[0]))
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    img[np.clip(rr + dy, 0, size[1] - 1), np.clip(cc + dx, 0, size[0] - 1)] = color

    for s in _stick_figure(px):
        if s.kind == "pose" and len(s.points) != 30:
            poly(s.points, (0, 0, 0))
    rr, cc = circle_perimeter(int(px[15, 1]), int(px[15, 0]), int(0.1 * PPU))
    for dy in (-1, 0, 1):
        img[rr + dy, cc] = 0
    poly(traj_px, (220, 0, 0))
    iio.imwrite(path, img)


def test_png_of_a_stick_figure_gives_joints_and_a_trajectory(tmp_path):
    cam = Camera()
    px = to_pixels(cam.project(_real_pose()), ORIGIN, PPU)
    wrist = px[_idx("right_wrist")[0]]
    traj = wrist + np.c_[np.linspace(0, -90, 10), np.linspace(0, -40, 10)]
    _draw_png(tmp_path / "fig.png", px, traj)
    sk = sketch_from_png(tmp_path / "fig.png", "a person waves the right hand", cam)
    err = np.linalg.norm(sk.joints - px, axis=1)
    assert err.mean() < 0.06 * np.ptp(px[:, 1]), err.mean()
    c = sk.conditions()
    assert list(c["trajectories_2d"]) == ["right_wrist"] and c["keypose_at"] == "first"
    with pytest.raises(ValueError, match="no stick figure in the pose colour"):
        sketch_from_png(tmp_path / "fig.png", pose_color=(0, 255, 0))
    (tmp_path / "x.png").write_bytes(b"\x89PNG not an image")
    with pytest.raises(ValueError, match="cannot read the image"):
        sketch_from_png(tmp_path / "x.png")
