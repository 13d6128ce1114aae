"""The capsule-bone human of Sketch2Anim: bone radii, checked joint arrays and capsule meshes.

Every bone of the 22-joint skeleton (:data:`~physlab.motion.skeleton.JOINT_NAMES`, ``(T, 22, 3)``
metres, y up) is a capsule — a cylinder closed by two hemispheres — whose radius depends on the
body part (:data:`BONE_RADII`), plus a head and two hands: the "default capsule-bone human
model" of Sketch2Anim (Sec. 3, "Output"). This module owns that geometry as pure numpy:
:func:`capsule_segments` (joints -> capsule axes and radii) and :func:`capsule_arrays`
(capsules -> triangle meshes with exact normals, vectorised over frames and capsules). It
draws nothing; :mod:`physlab.viz.scene_pyvista` and :mod:`physlab.viz.scene_mpl` do.
"""
from __future__ import annotations

import functools

import numpy as np

from physlab.motion.skeleton import JOINT_NAMES, PARENTS

__all__ = ["BONE_RADII", "capsule_arrays", "capsule_segments"]

_J = len(JOINT_NAMES)

#: (22,) float, capsule radius (metres) of the bone ending at each joint (row 0, the pelvis,
#: has no bone). Torso and thighs thick, forearms and feet thin (adult proportions).
BONE_RADII = np.array([
    0.0,                     # pelvis
    0.075, 0.075,            # pelvis -> hips
    0.095,                   # pelvis -> spine1
    0.065, 0.065,            # thighs
    0.10,                    # spine1 -> spine2
    0.048, 0.048,            # shins
    0.105,                   # spine2 -> spine3 (chest)
    0.036, 0.036,            # feet (ankle -> toe base)
    0.05,                    # spine3 -> neck
    0.06, 0.06,              # spine3 -> collars
    0.045,                   # neck -> head
    0.052, 0.052,            # collar -> shoulder
    0.044, 0.044,            # upper arms
    0.036, 0.036,            # forearms
])
BONE_RADII.setflags(write=False)

_HEAD = (0.02, 0.11, 1.9)      # head capsule: from head + a·u to head + b·u, radius k·r_neck
_HAND = (0.0, 0.075, 1.0)      # hand capsule: continues the forearm, radius k·r_forearm


def _check_joints(joints, name="joints"):
    x = np.asarray(joints, dtype=float)
    if x.ndim == 2:
        x = x[None]
    if x.ndim != 3 or x.shape[1:] != (_J, 3) or len(x) == 0:
        raise ValueError(f"{name} must have shape (T, {_J}, 3) or ({_J}, 3) (metres, y up), "
                         f"got {np.shape(joints)}")
    if not np.all(np.isfinite(x)):
        t, j = np.argwhere(~np.isfinite(x))[0][:2]
        raise ValueError(f"{name} contains NaN or inf (first at frame {t}, joint "
                         f"{JOINT_NAMES[j]}); clean or drop those frames first")
    return x


def _radii(radius):
    if radius is None:
        return np.array(BONE_RADII)
    r = np.asarray(radius, dtype=float)
    if r.ndim == 0:
        r = np.full(_J, float(r))
    if r.shape != (_J,) or np.any(r[1:] <= 0) or not np.all(np.isfinite(r)):
        raise ValueError(f"radius must be None, a float > 0 or a ({_J},) array of bone radii "
                         f"(> 0 for joints 1..21), got {radius!r}")
    return r


def capsule_segments(joints, radius=None):
    """The capsules of the capsule-bone human: 21 bones, a head and two hands.

    Parameters
    ----------
    joints : (T, 22, 3) or (22, 3) float array, metres.
    radius : None (:data:`BONE_RADII`), float (all bones) or (22,) float array (bone ending
        at each joint).

    Returns
    -------
    a, b : (T, 24, 3) float arrays, capsule axis end points (bones in child-joint order
        1..21, then head, left hand, right hand); r : (24,) float radii; joint : (24,) int,
        the joint each capsule belongs to (child joint of a bone, 15 head, 20 / 21 hands).
    """
    x = _check_joints(joints)
    r = _radii(radius)
    kids = np.arange(1, _J)
    a, b = [x[:, PARENTS[kids]]], [x[:, kids]]
    u = x[:, 15] - x[:, 12]
    u = u / np.maximum(np.linalg.norm(u, axis=-1, keepdims=True), 1e-9)   # neck -> head
    a.append(x[:, 15:16] + _HEAD[0] * u[:, None])
    b.append(x[:, 15:16] + _HEAD[1] * u[:, None])
    f = x[:, [20, 21]] - x[:, [18, 19]]
    f = f / np.maximum(np.linalg.norm(f, axis=-1, keepdims=True), 1e-9)    # forearm directions
    a.append(x[:, [20, 21]] + _HAND[0] * f)
    b.append(x[:, [20, 21]] + _HAND[1] * f)
    radii = np.r_[r[1:], _HEAD[2] * r[15], _HAND[2] * r[20], _HAND[2] * r[21]]
    joint = np.r_[kids, 15, 20, 21]
    return np.concatenate(a, axis=1), np.concatenate(b, axis=1), radii, joint


@functools.lru_cache(maxsize=4)
def _capsule_template(n_theta=16, n_phi=5):
    """Unit capsule: radial part ``A`` (n, 3) (= the outward normal), axial flag ``s`` (n,)
    (0 bottom, 1 top) and triangles (m, 3); a capsule of radius r from 0 to L·ẑ has points
    ``r A + L s ẑ``."""
    th = 2 * np.pi * np.arange(n_theta) / n_theta
    phis = np.r_[-np.pi / 2 + np.pi / 2 * np.arange(1, n_phi + 1) / n_phi,   # bottom, to 0
                 np.pi / 2 * np.arange(0, n_phi) / n_phi]                    # top, from 0
    s_ring = np.r_[np.zeros(n_phi), np.ones(n_phi)]
    ring = np.stack([np.cos(phis)[:, None] * np.cos(th), np.cos(phis)[:, None] * np.sin(th),
                     np.sin(phis)[:, None] * np.ones_like(th)], axis=-1)    # (2 n_phi, n_theta, 3)
    A = np.concatenate([[[0, 0, -1.0]], ring.reshape(-1, 3), [[0, 0, 1.0]]])
    s = np.r_[0.0, np.repeat(s_ring, n_theta), 1.0]
    n_r = 2 * n_phi
    idx = 1 + np.arange(n_r * n_theta).reshape(n_r, n_theta)
    nxt = np.roll(idx, -1, axis=1)
    bottom = np.stack([np.zeros(n_theta, int), nxt[0], idx[0]], axis=1)
    top = np.stack([np.full(n_theta, len(A) - 1), idx[-1], nxt[-1]], axis=1)
    q0, q1, q2, q3 = idx[:-1], nxt[:-1], nxt[1:], idx[1:]                    # quads between rings
    quads = np.concatenate([np.stack([q0, q1, q2], -1).reshape(-1, 3),
                            np.stack([q0, q2, q3], -1).reshape(-1, 3)])
    tris = np.concatenate([bottom, quads, top])
    for arr in (A, s, tris):
        arr.setflags(write=False)
    return A, s, tris


def _frames_from_axis(u):
    """(..., 3, 3) rotations whose third column is the unit vector ``u`` (..., 3)."""
    helper = np.where(np.abs(u[..., :1]) < 0.9, [1.0, 0, 0], [0, 1.0, 0])
    e1 = np.cross(helper, u)
    e1 /= np.maximum(np.linalg.norm(e1, axis=-1, keepdims=True), 1e-12)
    e2 = np.cross(u, e1)
    return np.stack([e1, e2, u], axis=-1)


def capsule_arrays(a, b, r, n_theta=16, n_phi=5):
    """Triangle meshes of capsules from ``a`` to ``b``, vectorised over frames and capsules.

    Parameters
    ----------
    a, b : (..., S, 3) float arrays, axis end points (metres); r : (S,) float radii.
    n_theta, n_phi : segments around the axis and per hemisphere.

    Returns
    -------
    points : (..., S·n, 3) float; normals : (..., S·n, 3) float unit outward normals;
    tris : (S·m, 3) int triangles (shared by all frames).
    """
    A, s, tris = _capsule_template(n_theta, n_phi)
    a, b = np.asarray(a, float), np.asarray(b, float)
    r = np.asarray(r, float)
    d = b - a
    L = np.linalg.norm(d, axis=-1)                                            # (..., S)
    u = np.where(L[..., None] > 1e-9, d / np.maximum(L, 1e-12)[..., None], [0, 1.0, 0])
    Q = _frames_from_axis(u)                                                  # (..., S, 3, 3)
    normals = np.einsum("...ij,nj->...ni", Q, A)                              # (..., S, n, 3)
    points = (a[..., None, :] + r[:, None, None] * normals
              + (L[..., None] * s)[..., None] * u[..., None, :])              # r A + L s u
    S, n = r.shape[0], len(A)
    faces = (tris[None] + n * np.arange(S)[:, None, None]).reshape(-1, 3)
    shape = points.shape[:-3] + (S * n, 3)
    return points.reshape(shape), normals.reshape(shape), faces
