"""Body constraints of a generated clip: rigid bones and feet on the ground.

A diffusion model that denoises joint positions (either feature representation of
:mod:`~physlab.motion.features`) predicts every joint independently, so nothing forces a
bone to keep its length from frame to frame or a foot to stay above the floor; an inference
guidance that pulls a few joints onto their targets makes it worse (it drags one joint, not
the body). :func:`rigid_bones` projects a clip onto a skeleton with constant bone lengths
(keeping every bone's direction) and :func:`ground_feet` lifts frames whose feet sink into
the floor. :func:`constrain_body` does both; :class:`~physlab.motion.sampling.Generator`
applies it to every clip unless told not to.

Shapes: joints ``(T, 22, 3)`` (or ``(B, T, 22, 3)``) in metres, y up, floor at ``y = 0``,
joint order and tree of :mod:`~physlab.motion.skeleton`.
"""
from __future__ import annotations

import numpy as np

from .skeleton import FOOT_JOINTS, PARENTS, bone_lengths, topological_order

__all__ = ["clip_bone_lengths", "rigid_bones", "ground_feet", "constrain_body",
           "FLOOR_TOLERANCE"]

#: A foot this far below the floor (m) counts as sinking in :func:`ground_feet`'s checks.
FLOOR_TOLERANCE = 0.02


def _check(joints, name="joints"):
    x = np.asarray(joints, dtype=float)
    if x.ndim not in (3, 4) or x.shape[-2:] != (len(PARENTS), 3) or x.shape[-3] < 1:
        raise ValueError(f"{name} must have shape (T, {len(PARENTS)}, 3) or (B, T, "
                         f"{len(PARENTS)}, 3) in metres, got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} contains NaN or inf")
    return x


def clip_bone_lengths(joints):
    """Per-bone length of a clip, the median over its frames: ``(22,)`` (``(B, 22)`` for a
    batch; entry 0, the pelvis, is 0). The median ignores the few frames a guidance or a
    bad denoising step stretched."""
    x = _check(joints)
    d = bone_lengths(x.reshape(-1, len(PARENTS), 3)).reshape(x.shape[:-2] + (-1,))  # (..., T, 21)
    out = np.zeros(x.shape[:-3] + (len(PARENTS),))
    out[..., 1:] = np.median(d, axis=-2)
    return out


def rigid_bones(joints, lengths=None):
    """Project a clip onto constant bone lengths, keeping the pelvis and every bone's
    direction: walking the tree from the pelvis, ``x'_j = x'_p + L_j (x_j − x_p)/|x_j − x_p|``.

    Parameters
    ----------
    joints : (T, 22, 3) or (B, T, 22, 3) float array (m).
    lengths : None (each clip's :func:`clip_bone_lengths`) or a (22,) / (B, 22) array of
        bone lengths (m; entry 0 unused), e.g. those of a keypose the user drew.

    Returns
    -------
    Array of the input's shape: every bone's length is ``lengths[j]`` in every frame. A
    bone of zero length in a frame keeps its direction from the skeleton's median pose.
    """
    x = _check(joints)
    L = clip_bone_lengths(x) if lengths is None else np.asarray(lengths, dtype=float)
    if L.shape != x.shape[:-3] + (len(PARENTS),) or not np.all(np.isfinite(L)) or np.any(L < 0):
        raise ValueError(f"lengths must be None or finite non-negative bone lengths of shape "
                         f"{x.shape[:-3] + (len(PARENTS),)}, got {np.shape(lengths)}")
    out = np.empty_like(x)
    out[..., 0, :] = x[..., 0, :]
    for j in topological_order(PARENTS):
        p = PARENTS[j]
        if p < 0:
            continue
        d = x[..., j, :] - x[..., p, :]                                      # (..., T, 3)
        n = np.linalg.norm(d, axis=-1, keepdims=True)
        fallback = np.median(d, axis=-2, keepdims=True)                      # (..., 1, 3)
        d = np.where(n > 1e-9, d, fallback)
        n = np.linalg.norm(d, axis=-1, keepdims=True)
        out[..., j, :] = out[..., p, :] + L[..., j, None, None] * d / np.maximum(n, 1e-12)
    return out


def ground_feet(joints, floor=0.0, feet=FOOT_JOINTS):
    """Lift every frame whose lowest foot joint is below ``floor`` by that much (the whole
    body, so bones stay rigid); other frames are unchanged.

    Parameters
    ----------
    joints : (T, 22, 3) or (B, T, 22, 3) float array (m).
    floor : float, floor height (m).
    feet : joint indices that may not go below the floor (default ankles and toes).

    Returns
    -------
    Array of the input's shape.
    """
    x = _check(joints)
    low = x[..., list(feet), 1].min(axis=-1)                                 # (..., T)
    lift = np.maximum(float(floor) - low, 0.0)
    out = x.copy()
    out[..., 1] += lift[..., None]
    return out


def constrain_body(joints, lengths=None, floor=0.0):
    """:func:`rigid_bones` then :func:`ground_feet`: the body constraints of a generated
    clip (Sketch2Anim's guidance is said to keep a plausible body; here it is enforced)."""
    return ground_feet(rigid_bones(joints, lengths), floor=floor)
