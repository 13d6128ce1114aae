"""The storyboard camera (physlab.motion.camera) against scipy's rotations and analytic views,
and the sketch augmentations of Sketch2Anim supp. B."""
import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from physlab.motion.camera import (BODY_PARTS, Camera, from_pixels, perturb_joints,
                                   perturb_proportions, random_camera, sketch_kwargs,
                                   to_pixels)
from physlab.motion.skeleton import PARENTS


def _pose(seed=0):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(22, 3))
    x[0] = 0.0
    return x


def test_front_view_keeps_x_and_y():
    x = _pose()
    np.testing.assert_allclose(Camera().project(x), x[:, :2], atol=1e-15)
    np.testing.assert_allclose(Camera(scale=1.5).project(x), 1.5 * x[:, :2], atol=1e-15)
    np.testing.assert_allclose(Camera().view_direction, [0, 0, -1], atol=1e-15)


@pytest.mark.parametrize("pitch, yaw, roll", [(20, -30, 0), (0, 45, 10), (30, 120, -60)])
def test_rotation_is_scipys_intrinsic_zxy(pitch, yaw, roll):
    cam = Camera(scale=0.8, pitch=pitch, yaw=yaw, roll=roll)
    R = Rotation.from_euler("ZXY", [roll, pitch, yaw], degrees=True).as_matrix()
    np.testing.assert_allclose(cam.rotation, R, atol=1e-12)
    x = _pose(1)
    np.testing.assert_allclose(cam.project(x), 0.8 * (x @ R.T)[:, :2], atol=1e-12)
    # orthographic: moving a point along the view direction does not move its image
    np.testing.assert_allclose(cam.project(x + 0.7 * cam.view_direction), cam.project(x),
                               atol=1e-12)


def test_angles_mean_what_the_docstring_says():
    forward = np.array([0.0, 0.0, 1.0])                 # the character's facing direction
    # yaw 90: the camera on the character's right, so walking forward goes right in the image
    np.testing.assert_allclose(Camera(yaw=90).project(forward), [1, 0], atol=1e-12)
    # pitch > 0 looks down: a point in front of the character appears lower than its feet
    assert Camera(pitch=30).project(forward)[1] < 0
    np.testing.assert_allclose(Camera(pitch=30).project([0, 1, 0]), [0, np.cos(np.pi / 6)],
                               atol=1e-12)
    # roll turns the picture counter-clockwise: the up axis leans left
    u, v = Camera(roll=90).project([0, 1, 0])
    np.testing.assert_allclose([u, v], [-1, 0], atol=1e-12)


def test_pixels_round_trip_with_y_down():
    uv = np.array([[0.0, 0.0], [1.0, 2.0], [-0.5, -1.0]])
    px = to_pixels(uv, origin=(256, 400), pixels_per_unit=100)
    np.testing.assert_allclose(px, [[256, 400], [356, 200], [206, 500]])
    np.testing.assert_allclose(from_pixels(px, (256, 400), 100), uv, atol=1e-12)


def test_camera_dict_round_trip_and_json():
    cam = Camera(scale=1.1, pitch=15, yaw=-40, roll=0)
    assert Camera.from_dict(json.loads(json.dumps(cam.to_dict()))) == cam


def test_random_camera_stays_in_the_papers_ranges():
    cams = [random_camera(s) for s in range(200)]
    p, y, s = (np.array([getattr(c, k) for c in cams]) for k in ("pitch", "yaw", "scale"))
    assert p.min() >= 0 and p.max() <= 30 and np.ptp(p) > 25
    assert y.min() >= -45 and y.max() <= 45 and np.ptp(y) > 80
    assert s.min() >= 0.8 and s.max() <= 1.2 and all(c.roll == 0 for c in cams)
    assert random_camera(3) == random_camera(np.random.default_rng(3))


def test_proportions_scale_whole_bones_and_carry_the_children():
    kp = Camera(pitch=20, yaw=30).project(_pose(2))                         # (22, 2)
    out, used = perturb_proportions(kp, rng=0)
    assert set(used) == set(BODY_PARTS) and all(0.6 <= f <= 1.6 for f in used.values())
    child = np.arange(1, 22)
    before = kp[child] - kp[PARENTS[child]]
    after = out[child] - out[PARENTS[child]]
    expect = np.ones(22)
    for part, bones in BODY_PARTS.items():
        expect[list(bones)] = used[part]
    np.testing.assert_allclose(after, expect[child, None] * before, atol=1e-12)
    np.testing.assert_array_equal(out[0], kp[0])
    same, _ = perturb_proportions(kp, factor=1.0)
    np.testing.assert_allclose(same, kp, atol=1e-12)
    batch, _ = perturb_proportions(np.stack([kp, kp]), rng=0)                # (..., 22, 2)
    np.testing.assert_allclose(batch[1], out, atol=1e-12)


def test_joint_noise_has_the_asked_spread():
    x = np.zeros((4000, 22, 2))
    n = perturb_joints(x, rng=0, sigma=0.02)
    assert abs(n.std() - 0.02) < 0.0005 and abs(n.mean()) < 0.0005


@pytest.mark.parametrize("call, match", [
    (lambda: Camera(scale=0), "scale must be > 0"),
    (lambda: Camera(pitch=float("nan")), "pitch must be a finite number"),
    (lambda: Camera(yaw="left"), "yaw must be a finite number"),
    (lambda: Camera().project(np.zeros((22, 2))), r"shape \(\.\.\., 3\)"),
    (lambda: Camera().project(np.full((22, 3), np.inf)), "NaN or inf"),
    (lambda: Camera.from_dict({"scale": 1, "fov": 40}), "unknown camera keys.*fov"),
    (lambda: to_pixels(np.zeros((3, 2)), (0, 0), 0), "pixels_per_unit must be > 0"),
    (lambda: from_pixels(np.zeros((3, 2)), (0,), 10), "origin must be"),
    (lambda: random_camera(0, pitch=(30, 0)), "pitch must be a"),
    (lambda: perturb_proportions(np.zeros((21, 2))), r"shape \(\.\.\., 22, d\)"),
    (lambda: perturb_proportions(np.zeros((22, 2)), parts=("tail",)), "unknown body parts"),
    (lambda: perturb_proportions(np.zeros((22, 2)), factor=(-1, 2)), "positive"),
    (lambda: perturb_joints(np.zeros((22, 2)), sigma=-0.1), "sigma must be"),
])
def test_bad_input(call, match):
    with pytest.raises((ValueError, TypeError), match=match):
        call()


def test_sketch_kwargs_project_the_condition():
    from physlab.motion.dataset import condition_from_window

    rng = np.random.default_rng(4)
    w = rng.normal(size=(40, 22, 3))
    cond = condition_from_window(w, t_r=12, keypose_at="last", joints=("pelvis", "head"))
    cam = Camera(scale=0.9, pitch=25, yaw=-20)
    kw = sketch_kwargs(cond, cam)
    assert kw["camera"] == cam and kw["keypose_at"] == "last"
    np.testing.assert_allclose(kw["keypose_2d"], cam.project(w[-1]), atol=1e-12)
    assert set(kw["trajectories_2d"]) == {"pelvis", "head"}
    np.testing.assert_allclose(kw["trajectories_2d"]["head"], cam.project(w[28:, 15]), atol=1e-12)
    noisy = sketch_kwargs(cond, cam, rng=0, noise=0.02, proportions=(0.6, 1.6))
    assert 0.005 < np.abs(noisy["trajectories_2d"]["pelvis"] - kw["trajectories_2d"]["pelvis"]
                          ).mean() < 0.03
    with pytest.raises(TypeError, match="camera must be"):
        sketch_kwargs(cond, {"scale": 1})
