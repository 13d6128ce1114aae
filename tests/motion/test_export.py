"""Tests of physlab.motion.export: 22-joint positions -> BVH -> forward kinematics round trip."""
import warnings

import numpy as np
import pytest

from physlab.motion import JOINT_NAMES, PARENTS, bone_lengths, forward_kinematics, read_bvh
from physlab.motion.export import (
    END_SITES,
    REST_DIRECTIONS,
    TPOSE_OFFSETS,
    joint_rotations,
    joints_to_bvh,
    joints_to_bvh_motion,
    rest_offsets,
)
from physlab.motion.skeleton import euler_to_matrix

MM = 1e-3


def _fk_clip(T=40, seed=0, scale=1.0, amplitude=35.0):
    """A rigid-skeleton clip: random smooth local rotations of a scaled, SMPL-like skeleton
    whose hips / shoulders are deliberately not symmetric (z offsets), root moving."""
    rng = np.random.default_rng(seed)
    offsets = np.array(TPOSE_OFFSETS) * scale
    offsets[[1, 2, 13, 14], 2] = [-0.018, -0.013, -0.02, -0.024]       # SMPL-like, not T-pose
    t = np.linspace(0, 1, T)[:, None, None]
    w, ph = rng.uniform(1, 4, (1, 22, 3)), rng.uniform(0, 2 * np.pi, (1, 22, 3))
    angles = amplitude * np.sin(2 * np.pi * w * t + ph)                     # (T, 22, 3) degrees
    R = euler_to_matrix(angles, "XYZ")
    root = np.c_[np.linspace(0, 1.5, T), 0.9 + 0.03 * np.sin(6 * t[:, 0, 0]), 0.4 * t[:, 0, 0]]
    return forward_kinematics(R, offsets, PARENTS, root)


def _read_joints(path):
    m = read_bvh(path)
    return m, m.joint_positions()[:, [m.joint_index(n) for n in JOINT_NAMES]]


# ----------------------------------------------------------------------------- round trip


@pytest.mark.parametrize("lengths", ["mean", "first"])
def test_round_trip_reproduces_all_joints_within_1mm(tmp_path, lengths):
    x = _fk_clip(seed=1)
    path = joints_to_bvh(x, tmp_path / "clip.bvh", fps=20, lengths=lengths)
    m, y = _read_joints(path)
    assert y.shape == x.shape
    assert np.abs(y - x).max() < 1 * MM                       # every joint, leaves included
    assert np.abs(y - x).max() < 1e-6                         # in fact exact up to the 10 digits
    assert m.frame_time == pytest.approx(1 / 20)
    assert m.n_joints == 22 + len(END_SITES)


@pytest.mark.parametrize("order", ["ZXY", "XYZ", "YZX"])
def test_round_trip_any_euler_order_and_scale(tmp_path, order):
    x = _fk_clip(T=25, seed=2, scale=0.8, amplitude=80.0)     # small person, large rotations
    _, y = _read_joints(joints_to_bvh(x, tmp_path / "c.bvh", order=order))
    assert np.abs(y - x).max() < 1 * MM


def test_bone_lengths_preserved(tmp_path):
    x = _fk_clip(seed=3)
    m, y = _read_joints(joints_to_bvh(x, tmp_path / "c.bvh"))
    np.testing.assert_allclose(bone_lengths(y), bone_lengths(x), atol=1e-6)
    # the file's offsets are the bone lengths
    off = np.array([m.offsets[m.joint_index(n)] for n in JOINT_NAMES])
    np.testing.assert_allclose(np.linalg.norm(off[1:], axis=1), bone_lengths(x)[0], atol=1e-6)


def test_single_frame_and_in_memory_motion():
    x = _fk_clip(T=1, seed=4)
    m = joints_to_bvh_motion(x, fps=30)
    y = m.joint_positions()[:, [m.joint_index(n) for n in JOINT_NAMES]]
    assert np.abs(y - x).max() < 1e-9
    assert m.channels[m.joint_index("pelvis")][:3] == ["Xposition", "Yposition", "Zposition"]
    assert all(len(m.channels[m.joint_index(n)]) == 3 for n in JOINT_NAMES[1:])
    assert m.fps == pytest.approx(30)


# ----------------------------------------------------------------------------- rest pose


def test_rest_pose_is_a_t_pose_on_the_floor():
    x = _fk_clip(seed=5)
    o = rest_offsets(x)
    rest = forward_kinematics(np.broadcast_to(np.eye(3), (1, 22, 3, 3)), o, PARENTS)[0]
    assert rest[:, 1].min() == pytest.approx(0.0, abs=1e-12)            # lowest joint on y = 0
    # arms horizontal along ±x, legs straight down, head above the pelvis
    for side, sign in (("left", 1), ("right", -1)):
        s, e, w = (rest[JOINT_NAMES.index(f"{side}_{k}")] for k in ("shoulder", "elbow", "wrist"))
        np.testing.assert_allclose([(e - s)[1], (w - e)[1], (e - s)[2]], 0, atol=1e-12)
        assert sign * (w - s)[0] > 0.4
        hip, ankle = (rest[JOINT_NAMES.index(f"{side}_{k}")] for k in ("hip", "ankle"))
        np.testing.assert_allclose((ankle - hip)[[0, 2]], 0, atol=1e-12)
    assert rest[15, 1] > rest[0, 1] + 0.4
    # single-child bones follow REST_DIRECTIONS; lengths from the data
    L = bone_lengths(x).mean(0)
    for j in (4, 7, 10, 16, 18, 20, 6, 15):
        np.testing.assert_allclose(o[j], L[j - 1] * REST_DIRECTIONS[j], atol=1e-12)


def test_default_rest_offsets_and_directions():
    np.testing.assert_array_equal(rest_offsets(), TPOSE_OFFSETS)
    np.testing.assert_allclose(np.linalg.norm(REST_DIRECTIONS[1:], axis=1), 1.0)
    # fixed reference: default skeleton height (floor to head joint) in metres
    rest = forward_kinematics(np.broadcast_to(np.eye(3), (1, 22, 3, 3)), TPOSE_OFFSETS, PARENTS)
    assert rest[0, :, 1].min() == pytest.approx(0.0, abs=1e-12)        # toes on the floor
    # 0.12 + 0.14 + 0.056 + 0.21 + 0.10 (spine, neck, head) + 0.09 + 0.39 + 0.42 + 0.065 (leg)
    assert rest[0, 15, 1] == pytest.approx(1.591, abs=1e-12)


def test_rotations_are_proper_and_leaves_identity():
    x = _fk_clip(T=10, seed=6)
    _, R = joint_rotations(x, rest_offsets(x))
    np.testing.assert_allclose(R @ R.transpose(0, 1, 3, 2), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-10)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-10)
    np.testing.assert_allclose(R[:, list(END_SITES)], np.broadcast_to(np.eye(3), (10, 5, 3, 3)))


def test_rotation_invariance_of_the_fit():
    """Rotating the whole clip about y only changes the root rotation channels."""
    x = _fk_clip(T=12, seed=7)
    c, s = np.cos(0.7), np.sin(0.7)
    Ry = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    xr = x @ Ry.T
    _, R0 = joint_rotations(x, rest_offsets(x))
    _, R1 = joint_rotations(xr, rest_offsets(x))
    np.testing.assert_allclose(R1[:, 1:], R0[:, 1:], atol=1e-9)
    np.testing.assert_allclose(R1[:, 0], Ry @ R0[:, 0], atol=1e-9)


# ----------------------------------------------------------------------------- non-rigid input


def test_non_rigid_input_warns_with_the_error(tmp_path):
    x = _fk_clip(T=20, seed=8)
    noisy = x + np.random.default_rng(0).normal(scale=0.01, size=x.shape)   # 1 cm jitter
    with pytest.warns(UserWarning, match="reproduces the joints only to"):
        joints_to_bvh(noisy, tmp_path / "n.bvh")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        joints_to_bvh(noisy, tmp_path / "n.bvh", tol=1.0)    # tolerance 1 m: silent
    _, y = _read_joints(tmp_path / "n.bvh")
    assert np.abs(y - noisy).max() < 0.06                    # still the closest rigid fit


# ----------------------------------------------------------------------------- errors


def test_errors(tmp_path):
    x = _fk_clip(T=5)
    with pytest.raises(ValueError, match=r"shape \(T, 22, 3\)"):
        joints_to_bvh(x[:, :21], tmp_path / "a.bvh")
    with pytest.raises(ValueError, match=r"shape \(T, 22, 3\)"):
        joints_to_bvh(x[0], tmp_path / "a.bvh")
    bad = x.copy()
    bad[2, 7, 1] = np.nan
    with pytest.raises(ValueError, match="NaN.*frame 2, joint left_ankle"):
        joints_to_bvh(bad, tmp_path / "a.bvh")
    with pytest.raises(ValueError, match="fps must be > 0"):
        joints_to_bvh(x, tmp_path / "a.bvh", fps=0)
    with pytest.raises(ValueError, match="order must be a permutation"):
        joints_to_bvh(x, tmp_path / "a.bvh", order="ZZY")
    with pytest.raises(ValueError, match="offsets must be a finite"):
        joints_to_bvh(x, tmp_path / "a.bvh", offsets=np.zeros((21, 3)))
    with pytest.raises(ValueError, match="lengths must be"):
        rest_offsets(x, lengths="median")
    assert not (tmp_path / "a.bvh").exists()
