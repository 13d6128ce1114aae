"""Tests of physlab.motion.skeleton: joint tables, Euler angles, forward kinematics."""
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from physlab.motion import skeleton
from physlab.motion.skeleton import (JOINT_NAMES, KINEMATIC_CHAINS, PARENTS, bone_lengths,
                                     euler_to_matrix, forward_kinematics, topological_order)

ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")


def test_joint_tables():
    assert len(JOINT_NAMES) == 22 and len(set(JOINT_NAMES)) == 22
    assert PARENTS.shape == (22,) and PARENTS[0] == -1
    assert np.all(PARENTS[1:] < np.arange(1, 22)) and np.all(PARENTS[1:] >= 0)
    # a few SMPL facts
    name = dict(enumerate(JOINT_NAMES))
    assert name[PARENTS[JOINT_NAMES.index("left_knee")]] == "left_hip"
    assert name[PARENTS[JOINT_NAMES.index("head")]] == "neck"
    assert name[PARENTS[JOINT_NAMES.index("left_collar")]] == "spine3"
    assert name[PARENTS[JOINT_NAMES.index("right_wrist")]] == "right_elbow"
    # every chain follows parent links
    assert len(KINEMATIC_CHAINS) == 5
    for chain in KINEMATIC_CHAINS:
        for p, c in zip(chain[:-1], chain[1:]):
            assert PARENTS[c] == p
    assert sorted({j for ch in KINEMATIC_CHAINS for j in ch}) == list(range(22))
    assert skeleton.joint_index("spine3") == 9
    with pytest.raises(ValueError, match="unknown joint"):
        skeleton.joint_index("tail")


@pytest.mark.parametrize("order", ORDERS)
def test_euler_to_matrix_matches_scipy(order):
    rng = np.random.default_rng(0)
    angles = rng.uniform(-180, 180, size=(7, 5, 3))
    R = euler_to_matrix(angles, order)
    ref = Rotation.from_euler(order, angles.reshape(-1, 3), degrees=True).as_matrix()
    assert R.shape == (7, 5, 3, 3)
    np.testing.assert_allclose(R.reshape(-1, 3, 3), ref, atol=1e-12)
    # invariant: proper rotations
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)


def test_euler_to_matrix_analytic_and_reference():
    # 90° about z maps x to y
    np.testing.assert_allclose(euler_to_matrix([90.0], "Z") @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    # ZXY = Rz Rx Ry: the last row does not depend on the z angle:
    # (-cos a1 sin a2, sin a1, cos a1 cos a2)
    R = euler_to_matrix([10.0, 20.0, 30.0], "zxy")
    a1, a2 = np.radians(20.0), np.radians(30.0)
    np.testing.assert_allclose(R[2], [-np.cos(a1) * np.sin(a2), np.sin(a1),
                                      np.cos(a1) * np.cos(a2)], atol=1e-15)
    assert R[0, 0] == pytest.approx(0.823172944646, abs=1e-11)     # fixed reference number
    with pytest.raises(ValueError, match="order"):
        euler_to_matrix([1.0, 2.0, 3.0], "XQZ")
    with pytest.raises(ValueError, match="shape"):
        euler_to_matrix([1.0, 2.0], "XYZ")


def _rz(deg):
    return euler_to_matrix([deg], "Z")


def test_forward_kinematics_three_joint_chain():
    offsets = np.array([[5.0, 5.0, 5.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    parents = np.array([-1, 0, 1])
    R = np.broadcast_to(np.eye(3), (2, 3, 3, 3)).copy()
    R[0, 0] = _rz(90)
    R[0, 1] = _rz(90)
    root = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 2.0]])
    x = forward_kinematics(R, offsets, parents, root)
    # frame 0: x1 = x0 + Rz90 e_x = (1, 1, 0); x2 = x1 + Rz180 e_x = (0, 1, 0)
    np.testing.assert_allclose(x[0], [[1, 0, 0], [1, 1, 0], [0, 1, 0]], atol=1e-12)
    # frame 1: identity rotations, a straight chain from the root
    np.testing.assert_allclose(x[1], [[0, 0, 2], [1, 0, 2], [2, 0, 2]], atol=1e-12)
    # without root positions the root sits at its offset
    x = forward_kinematics(R, offsets, parents)
    np.testing.assert_allclose(x[:, 0], [[5, 5, 5], [5, 5, 5]])


def test_forward_kinematics_invariants():
    rng = np.random.default_rng(1)
    T, J = 4, 22
    R = Rotation.random(T * J, random_state=2).as_matrix().reshape(T, J, 3, 3)
    offsets = rng.normal(size=(J, 3))
    x = forward_kinematics(R, offsets, PARENTS, np.zeros((T, 3)))
    # bones are rigid: lengths equal the offsets' norms in every frame
    np.testing.assert_allclose(bone_lengths(x), np.broadcast_to(
        np.linalg.norm(offsets[1:], axis=1), (T, J - 1)), atol=1e-12)
    # rotating the root rotates the whole pose about the root
    Q = Rotation.random(random_state=3).as_matrix()
    R2 = R.copy()
    R2[:, 0] = Q @ R[:, 0]
    x2 = forward_kinematics(R2, offsets, PARENTS, np.zeros((T, 3)))
    np.testing.assert_allclose(x2, x @ Q.T, atol=1e-12)
    # per-frame offsets (T, J, 3) give the same result as broadcast ones
    x3 = forward_kinematics(R, np.broadcast_to(offsets, (T, J, 3)), PARENTS, np.zeros((T, 3)))
    np.testing.assert_allclose(x3, x)
    # a permuted joint order (parents after children) gives the same positions
    perm = rng.permutation(J)
    inv = np.argsort(perm)
    parents_p = np.where(PARENTS[perm] < 0, -1, inv[np.maximum(PARENTS[perm], 0)])
    xp = forward_kinematics(R[:, perm], offsets[perm], parents_p, np.zeros((T, 3)))
    np.testing.assert_allclose(xp, x[:, perm], atol=1e-12)
    order = topological_order(parents_p)
    pos = np.argsort(order)
    assert all(pos[p] < pos[j] for j, p in enumerate(parents_p) if p >= 0)


def test_topological_order_rejects_cycles_and_bad_shapes():
    with pytest.raises(ValueError, match="cycle"):
        topological_order([-1, 2, 1])
    with pytest.raises(ValueError, match="parents"):
        topological_order([-1, 5])
    with pytest.raises(ValueError, match="rotations"):
        forward_kinematics(np.zeros((2, 3, 3)), np.zeros((3, 3)), [-1, 0, 1])


def test_bone_lengths():
    x = np.zeros((2, 22, 3))
    x[:, 1] = [0.0, -3.0, 4.0]          # left_hip 5 from the pelvis
    b = bone_lengths(x)
    assert b.shape == (2, 21)
    assert b[0, 0] == pytest.approx(5.0)
    assert b[1, 3] == pytest.approx(5.0)  # left_knee (at origin) to left_hip
    with pytest.raises(ValueError, match="shape"):
        bone_lengths(np.zeros((2, 21, 3)))


def test_import_does_not_pull_torch():
    code = ("import sys, physlab.motion, physlab.motion.bvh, physlab.motion.skeleton; "
            "assert 'torch' not in sys.modules, 'physlab.motion imported torch'")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)
