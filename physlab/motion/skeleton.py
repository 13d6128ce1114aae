"""The 22-joint HumanML3D / SMPL skeleton, Euler angles and forward kinematics.

Joint arrays are ``(T, 22, 3)`` float world positions in metres, y up, in the order of
:data:`JOINT_NAMES` (the first 22 SMPL body joints, as used by HumanML3D [Guo et al. 2022]
and Sketch2Anim). :data:`PARENTS` is the SMPL kinematic tree and :data:`KINEMATIC_CHAINS`
the five chains HumanML3D draws (``t2m_kinematic_chain``).

Rotation conventions (the BVH ones):

* ``euler_to_matrix(angles, "ZXY")`` is the *intrinsic* rotation
  ``R = R_z(a0) @ R_x(a1) @ R_y(a2)``: rotate about z, then about the new x, then the new y.
  It equals ``scipy.spatial.transform.Rotation.from_euler("ZXY", angles, degrees=True)``
  (upper-case = intrinsic). In a BVH file the rotation channels of a joint, read left to
  right, give exactly this order.
* forward kinematics composes parent-to-child: the world rotation of joint ``j`` is
  ``G_j = G_p @ R_j`` and its world position ``x_j = x_p + G_p @ o_j`` where ``p`` is its
  parent and ``o_j`` its offset (translation in the parent's frame).
"""
from __future__ import annotations

import numpy as np

__all__ = [
    "JOINT_NAMES", "PARENTS", "KINEMATIC_CHAINS", "FOOT_JOINTS", "joint_index", "bone_lengths",
    "euler_to_matrix", "forward_kinematics", "topological_order",
]

#: The 22 body joints in SMPL / HumanML3D order.
JOINT_NAMES = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
    "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist",
)

#: (22,) int parent of each joint (-1 for the pelvis); SMPL kinematic tree.
PARENTS = np.array([-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19])
PARENTS.setflags(write=False)

#: HumanML3D ``t2m_kinematic_chain``: right leg, left leg, spine + head, right arm, left arm.
KINEMATIC_CHAINS = (
    (0, 2, 5, 8, 11),
    (0, 1, 4, 7, 10),
    (0, 3, 6, 9, 12, 15),
    (9, 14, 17, 19, 21),
    (9, 13, 16, 18, 20),
)

#: Ankles and feet (toes), the joints that touch the ground.
FOOT_JOINTS = (7, 8, 10, 11)


def joint_index(name):
    """Index of a joint name in :data:`JOINT_NAMES`; ValueError listing the names if unknown."""
    try:
        return JOINT_NAMES.index(name)
    except ValueError:
        raise ValueError(f"unknown joint {name!r}; expected one of {', '.join(JOINT_NAMES)}") \
            from None


def bone_lengths(joints, parents=PARENTS):
    """Length of every bone (joint to its parent) in every frame.

    Parameters
    ----------
    joints : (T, J, 3) float array of positions (any length unit).
    parents : (J,) int array, -1 for roots; default :data:`PARENTS` (J = 22).

    Returns
    -------
    (T, B) float array, ``B`` = number of non-root joints, in joint order (for the
    22-joint skeleton: ``B = 21``, column ``j - 1`` is the bone ending at joint ``j``).
    """
    joints = np.asarray(joints, dtype=float)
    parents = np.asarray(parents)
    if joints.ndim != 3 or joints.shape[1:] != (len(parents), 3):
        raise ValueError(f"joints must have shape (T, {len(parents)}, 3), got {joints.shape}")
    child = np.flatnonzero(parents >= 0)
    return np.linalg.norm(joints[:, child] - joints[:, parents[child]], axis=-1)


def _axis_rotation(angles_rad, axis):
    """Elementary rotations about ``axis`` ("X", "Y" or "Z"): (...,) radians -> (..., 3, 3)."""
    c, s = np.cos(angles_rad), np.sin(angles_rad)
    one, zero = np.ones_like(c), np.zeros_like(c)
    if axis == "X":
        rows = ((one, zero, zero), (zero, c, -s), (zero, s, c))
    elif axis == "Y":
        rows = ((c, zero, s), (zero, one, zero), (-s, zero, c))
    elif axis == "Z":
        rows = ((c, -s, zero), (s, c, zero), (zero, zero, one))
    else:
        raise ValueError(f"rotation axis must be 'X', 'Y' or 'Z', got {axis!r}")
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def euler_to_matrix(angles_deg, order="ZXY"):
    """Rotation matrices from intrinsic Euler angles in degrees (the BVH convention).

    ``R = R_{order[0]}(a[..., 0]) @ R_{order[1]}(a[..., 1]) @ R_{order[2]}(a[..., 2])``,
    i.e. intrinsic rotations in the given order; equal to scipy's
    ``Rotation.from_euler(order.upper(), angles, degrees=True).as_matrix()``.

    Parameters
    ----------
    angles_deg : (..., k) float array of angles in degrees, ``k = len(order)``.
    order : str of the letters X, Y, Z (case-insensitive), usually one of the six
        Tait–Bryan orders XYZ, XZY, YXZ, YZX, ZXY, ZYX; any length >= 1 is accepted
        (a BVH joint may have fewer than three rotation channels).

    Returns
    -------
    (..., 3, 3) float array of rotation matrices.
    """
    order = str(order).upper()
    if not order or any(a not in "XYZ" for a in order):
        raise ValueError(f"order must be a string of the axes X, Y, Z such as 'ZXY', got "
                         f"{order!r}")
    a = np.radians(np.asarray(angles_deg, dtype=float))
    if a.ndim == 0 or a.shape[-1] != len(order):
        raise ValueError(f"angles must have shape (..., {len(order)}) for order {order!r}, got "
                         f"{a.shape}")
    R = _axis_rotation(a[..., 0], order[0])
    for k in range(1, len(order)):
        R = R @ _axis_rotation(a[..., k], order[k])
    return R


def topological_order(parents):
    """Joint indices ordered so that every parent comes before its children.

    Parameters
    ----------
    parents : (J,) int array, -1 for roots.

    Returns
    -------
    (J,) int array. ValueError if ``parents`` has a cycle or an out-of-range index.
    """
    parents = np.asarray(parents, dtype=int)
    J = len(parents)
    if np.any((parents < -1) | (parents >= J)):
        raise ValueError(f"parents must lie in -1..{J - 1}, got {parents.tolist()}")
    if np.all(parents < np.arange(J)):
        return np.arange(J)
    order, placed = [], np.zeros(J, dtype=bool)
    frontier = list(np.flatnonzero(parents < 0))
    children = [[] for _ in range(J)]
    for j, p in enumerate(parents):
        if p >= 0:
            children[p].append(j)
    while frontier:
        j = frontier.pop()
        order.append(j)
        placed[j] = True
        frontier.extend(children[j])
    if not placed.all():
        raise ValueError(f"parents has a cycle through joints {np.flatnonzero(~placed).tolist()}")
    return np.array(order)


def forward_kinematics(rotations, offsets, parents, root_positions=None):
    """World joint positions from local rotations and offsets (BVH-style FK).

    ``G_j = G_p R_j`` and ``x_j = x_p + G_p o_j`` (``p`` = parent of ``j``); a root joint
    (parent -1) has ``G_j = R_j`` and ``x_j = root_positions`` (which *replace* its offset,
    as BVH position channels do) or ``o_j`` when ``root_positions`` is None.

    Parameters
    ----------
    rotations : (T, J, 3, 3) float array, local rotation of each joint relative to its parent.
    offsets : (J, 3) or (T, J, 3) float array, translation of each joint in its parent's frame
        (per frame when the skeleton has translation channels on inner joints).
    parents : (J,) int array, -1 for roots (any order; evaluated in topological order).
    root_positions : None or (T, 3) float array, world positions of the root joint(s).

    Returns
    -------
    (T, J, 3) float array of world positions, in the units of ``offsets``.
    """
    R = np.asarray(rotations, dtype=float)
    if R.ndim != 4 or R.shape[2:] != (3, 3):
        raise ValueError(f"rotations must have shape (T, J, 3, 3), got {R.shape}")
    T, J = R.shape[:2]
    parents = np.asarray(parents, dtype=int)
    if parents.shape != (J,):
        raise ValueError(f"parents must have shape ({J},) to match rotations, got {parents.shape}")
    o = np.asarray(offsets, dtype=float)
    if o.shape == (J, 3):
        o = np.broadcast_to(o, (T, J, 3))
    elif o.shape != (T, J, 3):
        raise ValueError(f"offsets must have shape ({J}, 3) or ({T}, {J}, 3), got {o.shape}")
    if root_positions is not None:
        root_positions = np.asarray(root_positions, dtype=float)
        if root_positions.shape != (T, 3):
            raise ValueError(f"root_positions must have shape ({T}, 3), got "
                             f"{root_positions.shape}")
    G = np.empty_like(R)         # (T, J, 3, 3) world rotations
    x = np.empty((T, J, 3))      # (T, J, 3) world positions
    for j in topological_order(parents):
        p = parents[j]
        if p < 0:
            G[:, j] = R[:, j]
            x[:, j] = o[:, j] if root_positions is None else root_positions
        else:
            G[:, j] = G[:, p] @ R[:, j]
            x[:, j] = x[:, p] + np.einsum("tab,tb->ta", G[:, p], o[:, j])
    return x
