"""Export 22-joint position clips ``(T, 22, 3)`` as BVH files (for Blender, MotionBuilder, ...).

A BVH skeleton is rigid: each joint ``j`` has a fixed ``OFFSET`` ``o_j`` in its parent's
frame and, per frame, a local rotation ``R_j``; forward kinematics gives
``G_j = G_p R_j`` and ``x_j = x_p + G_p o_j`` (:func:`physlab.motion.skeleton.forward_kinematics`).
Generated motions (HumanML3D, Sketch2Anim) are joint *positions*, so the rotations have to be
recovered. The construction used here:

Rest pose ("T-pose-like", character facing +z, y up, left = +x; :data:`TPOSE_OFFSETS`)
    legs straight down, feet forward and slightly down, spine and neck straight up,
    collar -> shoulder -> elbow -> wrist horizontal along ±x (arms stretched sideways).
    The children of the two branching joints — the pelvis (hips, spine1) and spine3 (neck,
    collars) — keep the geometry *measured in the data*: their bone vectors are expressed in
    a body frame of the branching joint (y towards the spine / neck child, x from the right
    to the left child, ``z = x × y`` forward) and averaged over frames. Every other bone gets
    its canonical direction :data:`REST_DIRECTIONS` times its length in the data (first frame
    or mean over frames).

Rotations, per frame, parents before children
    * branching joint (several children ``c``): the world rotation ``G_j`` is the Kabsch fit
      ``argmin_G Σ_c |G o_c − d_c|²`` over its child bones ``d_c = x_c − x_j`` [Kabsch 1976],
      exact when the children form a rigid configuration (true for SMPL / HumanML3D
      skeletons, whose pelvis -> hips / spine1 and spine3 -> neck / collars offsets are fixed);
    * one child: the *swing* ``R_j`` = shortest-arc rotation taking ``o_c`` to
      ``G_p^T d_c`` (the posed bone in the parent's frame), by Rodrigues' formula;
    * leaf (feet, head, wrists): ``R_j = I``.

    The twist of a bone about its own axis is unobservable from joint positions: a rotation
    about the bone moves no joint of that bone. Leaves therefore get zero rotation and
    single-child joints the twist-free swing relative to their parent; a twist hidden in the
    data (e.g. a forearm roll) is lost, though every joint *position* is reproduced.

Exactness: when the input comes from a rigid skeleton (constant bone lengths and rigid
branching joints — any forward-kinematics output, HumanML3D included), reading the file
back and running forward kinematics reproduces all 22 joint positions to float precision
(the file stores 10 significant digits). Otherwise (a generated clip whose bone lengths
drift) the BVH is the closest rigid skeleton and :func:`joints_to_bvh_motion` warns with the
largest position error.
"""
from __future__ import annotations

import warnings

import numpy as np

from .bvh import BVHMotion, write_bvh
from .features import _check_joints
from .skeleton import JOINT_NAMES, PARENTS, forward_kinematics

__all__ = [
    "END_SITES",
    "REST_DIRECTIONS",
    "TPOSE_OFFSETS",
    "joint_rotations",
    "joints_to_bvh",
    "joints_to_bvh_motion",
    "rest_offsets",
]

_J = len(JOINT_NAMES)
_CHILDREN = tuple(tuple(int(c) for c in np.flatnonzero(PARENTS == j)) for j in range(_J))

#: Branching joint -> (child defining the frame's y axis, left child, right child).
_BODY_FRAMES = {0: (3, 1, 2), 9: (12, 13, 14)}

#: (22, 3) float, default T-pose offsets in metres (joint in its parent's frame; row 0 is the
#: pelvis height above the floor). Bone lengths approximate the SMPL neutral body; character
#: faces +z, y up, left = +x.
TPOSE_OFFSETS = np.array([
    [0.0, 0.965, 0.0],       # pelvis (root rest position: toes on the floor)
    [0.06, -0.09, 0.0],      # left_hip
    [-0.06, -0.09, 0.0],     # right_hip
    [0.0, 0.12, 0.0],        # spine1
    [0.0, -0.39, 0.0],       # left_knee
    [0.0, -0.39, 0.0],       # right_knee
    [0.0, 0.14, 0.0],        # spine2
    [0.0, -0.42, 0.0],       # left_ankle
    [0.0, -0.42, 0.0],       # right_ankle
    [0.0, 0.056, 0.0],       # spine3
    [0.0, -0.065, 0.125],    # left_foot (toe base: forward, slightly down)
    [0.0, -0.065, 0.125],    # right_foot
    [0.0, 0.21, 0.0],        # neck
    [0.075, 0.115, 0.0],     # left_collar
    [-0.075, 0.115, 0.0],    # right_collar
    [0.0, 0.10, 0.0],        # head
    [0.12, 0.0, 0.0],        # left_shoulder
    [-0.12, 0.0, 0.0],       # right_shoulder
    [0.26, 0.0, 0.0],        # left_elbow
    [-0.26, 0.0, 0.0],       # right_elbow
    [0.265, 0.0, 0.0],       # left_wrist
    [-0.265, 0.0, 0.0],      # right_wrist
])
TPOSE_OFFSETS.setflags(write=False)

#: (22, 3) float, unit rest direction of the bone ending at each joint, in its parent's frame
#: (row 0 is zero): the directions of :data:`TPOSE_OFFSETS`.
REST_DIRECTIONS = np.zeros((_J, 3))
REST_DIRECTIONS[1:] = TPOSE_OFFSETS[1:] / np.linalg.norm(TPOSE_OFFSETS[1:], axis=1, keepdims=True)
REST_DIRECTIONS.setflags(write=False)

#: Leaf joint -> End Site offset (metres, in the leaf's frame): toe tips, top of the head,
#: finger tips. They only give Blender a bone tail; no input position depends on them.
END_SITES = {10: (0.0, 0.0, 0.06), 11: (0.0, 0.0, 0.06), 15: (0.0, 0.12, 0.0),
             20: (0.08, 0.0, 0.0), 21: (-0.08, 0.0, 0.0)}


# ----------------------------------------------------------------------------- small rotations


def _normalize(v, eps=1e-12):
    """Unit vectors along the last axis; zero vectors stay zero."""
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, eps)


def _body_frame(x, j):
    """(T, 3, 3) rotation whose columns are the body axes (x left, y up, z forward) of the
    branching joint ``j`` in each frame of ``x`` (T, 22, 3)."""
    up, left, right = _BODY_FRAMES[j]
    y = _normalize(x[:, up] - x[:, j])                       # (T, 3)
    lat = x[:, left] - x[:, right]
    xa = _normalize(lat - np.sum(lat * y, -1, keepdims=True) * y)   # Gram–Schmidt
    z = np.cross(xa, y)
    return np.stack([xa, y, z], axis=-1)                     # (T, 3, 3) columns x, y, z


def _shortest_arc(a, b, eps=1e-12):
    """Rotation taking direction ``a`` to direction ``b`` about ``a × b`` (Rodrigues):
    ``R = I + [v]× + [v]×² / (1 + c)`` with ``v = â × b̂``, ``c = â · b̂``.

    a, b : (..., 3) float (need not be unit; zero vectors give the identity).
    Returns (..., 3, 3); antiparallel pairs rotate by π about an axis orthogonal to ``a``.
    """
    a, b = np.broadcast_arrays(_normalize(a), _normalize(b))
    v = np.cross(a, b)                                       # (..., 3)
    c = np.sum(a * b, axis=-1)                               # (...,)
    K = np.zeros(a.shape + (3,))                             # [v]×
    K[..., 0, 1], K[..., 0, 2] = -v[..., 2], v[..., 1]
    K[..., 1, 0], K[..., 1, 2] = v[..., 2], -v[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -v[..., 1], v[..., 0]
    anti = c < -1 + 1e-9
    R = np.eye(3) + K + (K @ K) / np.where(anti, 1.0, 1 + c)[..., None, None]
    if np.any(anti):                                         # π turn about any axis ⟂ a
        aa = a[anti]
        helper = np.where(np.abs(aa[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        n = _normalize(np.cross(aa, helper))
        R[anti] = 2 * n[:, :, None] * n[:, None, :] - np.eye(3)
    degenerate = (np.linalg.norm(a, axis=-1) < eps) | (np.linalg.norm(b, axis=-1) < eps)
    R[degenerate] = np.eye(3)
    return R


def _kabsch(P, Q):
    """Rotations ``G`` (T, 3, 3) minimising ``Σ_k |G p_k − q_k|²`` [Kabsch 1976].

    P : (K, 3) rest vectors; Q : (T, K, 3) posed vectors. ``H = Σ_k p_k q_kᵀ = U S Vᵀ``,
    ``G = V diag(1, 1, det(V Uᵀ)) Uᵀ`` (the sign fix excludes reflections).
    """
    H = np.einsum("ka,tkb->tab", P, Q)                       # (T, 3, 3)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.transpose(0, 2, 1) @ U.transpose(0, 2, 1)))
    D = np.broadcast_to(np.eye(3), H.shape).copy()
    D[:, 2, 2] = np.where(d == 0, 1.0, d)
    return Vt.transpose(0, 2, 1) @ D @ U.transpose(0, 2, 1)


# ----------------------------------------------------------------------------- rest pose


def rest_offsets(joints=None, lengths="mean"):
    """T-pose-like rest offsets of the 22-joint skeleton, with bone lengths from data.

    Bones of branching joints (pelvis -> hips / spine1, spine3 -> neck / collars) keep the
    data's geometry in the joint's body frame (see the module docstring); every other bone
    is its :data:`REST_DIRECTIONS` times its length. Row 0 is the pelvis's rest position
    ``(0, h, 0)``, ``h`` putting the lowest joint of the rest pose on the floor ``y = 0``.

    Parameters
    ----------
    joints : None or (T, 22, 3) float array, metres, y up; None returns
        :data:`TPOSE_OFFSETS`.
    lengths : ``"mean"`` (bone lengths and branching geometry averaged over frames) or
        ``"first"`` (from frame 0).

    Returns
    -------
    (22, 3) float array of offsets (metres), joint in its parent's frame.
    """
    if joints is None:
        return np.array(TPOSE_OFFSETS)
    if lengths not in ("mean", "first"):
        raise ValueError(f"lengths must be 'mean' or 'first', got {lengths!r}")
    x = _check_joints(joints)
    if lengths == "first":
        x = x[:1]
    d = x[:, 1:] - x[:, PARENTS[1:]]                          # (T, 21, 3) bone vectors
    offsets = np.zeros((_J, 3))
    offsets[1:] = np.linalg.norm(d, axis=-1).mean(0)[:, None] * REST_DIRECTIONS[1:]
    for j, (up, left, right) in _BODY_FRAMES.items():
        F = _body_frame(x, j)                                 # (T, 3, 3)
        for c in (up, left, right):
            offsets[c] = np.einsum("tba,tb->a", F, x[:, c] - x[:, j]) / len(x)   # Fᵀ d_c
    rest = forward_kinematics(np.broadcast_to(np.eye(3), (1, _J, 3, 3)), offsets, PARENTS)
    offsets[0] = (0.0, -rest[0, :, 1].min(), 0.0)
    return offsets


def joint_rotations(joints, offsets):
    """World and local joint rotations that pose ``offsets`` onto ``joints``.

    Branching joints: Kabsch fit of all child bones; single-child joints: swing (shortest
    arc) in the parent's frame; leaves: identity local rotation (module docstring).

    Parameters
    ----------
    joints : (T, 22, 3) float array, metres.
    offsets : (22, 3) float array, rest offsets (e.g. :func:`rest_offsets`).

    Returns
    -------
    G : (T, 22, 3, 3) world rotations; R : (T, 22, 3, 3) local rotations ``G_pᵀ G_j``.
    """
    x = _check_joints(joints)
    o = np.asarray(offsets, dtype=float)
    if o.shape != (_J, 3) or not np.all(np.isfinite(o)):
        raise ValueError(f"offsets must be a finite ({_J}, 3) array, got shape {o.shape}")
    T = len(x)
    G = np.empty((T, _J, 3, 3))
    R = np.empty((T, _J, 3, 3))
    eye = np.broadcast_to(np.eye(3), (T, 3, 3))
    for j in range(_J):                                       # PARENTS[j] < j: parents first
        p = PARENTS[j]
        Gp = G[:, p] if p >= 0 else eye
        kids = _CHILDREN[j]
        if len(kids) >= 2:
            G[:, j] = _kabsch(o[list(kids)], x[:, list(kids)] - x[:, j:j + 1])
            R[:, j] = Gp.transpose(0, 2, 1) @ G[:, j]
        elif len(kids) == 1:
            c = kids[0]
            d_local = np.einsum("tba,tb->ta", Gp, x[:, c] - x[:, j])     # G_pᵀ d_c
            R[:, j] = _shortest_arc(o[c], d_local)
            G[:, j] = Gp @ R[:, j]
        else:
            R[:, j] = np.eye(3)
            G[:, j] = Gp
    return G, R


# ----------------------------------------------------------------------------- BVH


def _check_order(order):
    order = str(order).upper()
    if sorted(order) != ["X", "Y", "Z"]:
        raise ValueError(f"order must be a permutation of 'XYZ' such as 'ZXY', got {order!r}")
    return order


def joints_to_bvh_motion(joints, fps=20, offsets=None, order="ZXY", lengths="mean", tol=1e-3):
    """A :class:`~physlab.motion.bvh.BVHMotion` that reproduces a 22-joint clip.

    Joints are named as :data:`JOINT_NAMES`; the pelvis has
    ``Xposition Yposition Zposition`` + three rotation channels, every other joint three
    rotation channels (in ``order``); leaves get ``End Site`` s (:data:`END_SITES`). Units
    are metres (Blender imports them with scale 1). Euler angles are unwrapped over time so
    the curves have no ±360° jumps.

    Parameters
    ----------
    joints : (T, 22, 3) float array, metres, y up (ValueError on other shapes or NaN).
    fps : float > 0, frame rate (Hz); ``Frame Time = 1 / fps``.
    offsets : None or (22, 3) float array of rest offsets; None = :func:`rest_offsets`
        ``(joints, lengths)``.
    order : rotation channel order, a permutation of ``"XYZ"`` (intrinsic, as in the file).
    lengths : ``"mean"`` or ``"first"``, passed to :func:`rest_offsets`.
    tol : float (metres); if forward kinematics of the result misses an input joint by more
        than ``tol`` (non-rigid input or ill-fitting ``offsets``) a warning gives the error.

    Returns
    -------
    :class:`BVHMotion` with ``22 + 5`` joints (the 22 plus 5 end sites) in depth-first file
    order; ``[m.joint_index(n) for n in JOINT_NAMES]`` selects the 22.
    """
    from scipy.spatial.transform import Rotation

    x = _check_joints(joints)
    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    order = _check_order(order)
    o = rest_offsets(x, lengths) if offsets is None else np.array(offsets, dtype=float)
    _, R = joint_rotations(x, o)                               # (T, 22, 3, 3)
    T = len(x)
    # intrinsic Euler angles (upper-case in scipy) in degrees, unwrapped over time
    with warnings.catch_warnings():   # at gimbal lock scipy still returns exact angles
        warnings.filterwarnings("ignore", message=".*[Gg]imbal lock.*")
        eul = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_euler(order, degrees=True)
    eul = np.unwrap(eul.reshape(T, _J, 3), period=360.0, axis=0)      # (T, 22, 3)
    rot_channels = [f"{a}rotation" for a in order]
    # BVH nests joints, so the file (and write_bvh's channel columns) lists them depth-first
    names, parents, offs, channels, cols, pos = [], [], [], [], [np.asarray(x[:, 0])], {}

    def visit(j, parent):
        pos[j] = len(names)
        names.append(JOINT_NAMES[j])
        parents.append(parent)
        offs.append(o[j])
        channels.append((["Xposition", "Yposition", "Zposition"] if j == 0 else [])
                        + rot_channels)
        cols.append(eul[:, j])
        for c in _CHILDREN[j]:
            visit(c, pos[j])
        if j in END_SITES:
            names.append(f"{JOINT_NAMES[j]}_End")
            parents.append(pos[j])
            offs.append(END_SITES[j])
            channels.append([])

    visit(0, -1)
    m = BVHMotion(names=names, parents=np.array(parents), offsets=np.array(offs),
                  channels=channels, frame_time=1.0 / fps,
                  motion=np.concatenate(cols, axis=1))              # (T, 3 + 66)
    order22 = [pos[j] for j in range(_J)]                           # JOINT_NAMES -> file order
    err = np.linalg.norm(m.joint_positions()[:, order22] - x, axis=-1)   # (T, 22)
    if err.max() > tol:
        t, j = np.unravel_index(np.argmax(err), err.shape)
        warnings.warn(f"the BVH reproduces the joints only to {1000 * err.max():.1f} mm "
                      f"(frame {t}, {JOINT_NAMES[j]}): a BVH skeleton is rigid, and these "
                      f"joints have varying bone lengths or non-rigid hips / shoulders (or "
                      f"offsets that do not fit); the file holds the closest rigid skeleton",
                      stacklevel=2)
    return m


def joints_to_bvh(joints, path, fps=20, offsets=None, order="ZXY", lengths="mean", tol=1e-3):
    """Write a 22-joint clip ``(T, 22, 3)`` (metres, y up) as a BVH file that opens in Blender.

    Builds :func:`joints_to_bvh_motion` and writes it atomically with
    :func:`~physlab.motion.bvh.write_bvh`. The file lists joints depth-first (as BVH
    nests them), so select them by name when reading back::

        m = read_bvh(path)
        x = m.joint_positions()[:, [m.joint_index(n) for n in JOINT_NAMES]]   # (T, 22, 3)

    ``x`` reproduces ``joints`` to float precision when they come from a rigid skeleton (see
    the module docstring for the rest pose, the rotation fit and the unobservable twist).

    In Blender: File > Import > Motion Capture (.bvh) with the default axes (Forward -Z,
    Up Y) and Scale 1 — lengths are metres; the armature rests in the T-pose.

    Parameters
    ----------
    joints : (T, 22, 3) float array, metres.
    path : str or Path of the ``.bvh`` file to (over)write.
    fps, offsets, order, lengths, tol : as in :func:`joints_to_bvh_motion`.

    Returns
    -------
    :class:`~pathlib.Path` of the written file.
    """
    return write_bvh(path, joints_to_bvh_motion(joints, fps=fps, offsets=offsets, order=order,
                                                lengths=lengths, tol=tol))
