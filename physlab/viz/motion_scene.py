"""What a 3-D motion view shows, whatever draws it: colours, checked inputs, ground, ghosts.

Both renderers (:mod:`physlab.viz.scene_pyvista`, :mod:`physlab.viz.scene_mpl`) take the same
arguments and draw the same scene: the clip ``(T, 22, 3)`` (metres, y up), an optional
keypose ``(22, 3)`` in red and joint trajectories ``(t_r, 3)`` (NaN rows are gaps) in green,
as in Sketch2Anim's figures (Fig. 1, Fig. A1), over a ground plane at the lowest capsule
point. This module owns the shared part: :data:`COLORS`, the argument checks with their
messages (:func:`_prepare`), the ground height and extent, and which frames a strobe ghosts
(:func:`_strobe_indices`) in which shades (:func:`_strobe_colors`). Pure numpy.
"""
from __future__ import annotations

import numpy as np

from physlab.motion.skeleton import JOINT_NAMES, joint_index
from physlab.viz.capsules import _J, _check_joints, _radii, capsule_segments

__all__ = ["COLORS"]

#: RGB colours in [0, 1]: Sketch2Anim draws the keypose in red and trajectories in green.
COLORS = {
    "body": (0.80, 0.82, 0.86),
    "keypose": (1.0, 0.0, 0.0),
    "trajectory": (0.0, 0.85, 0.0),
    "ground_light": (0.93, 0.93, 0.93),
    "ground_dark": (0.80, 0.80, 0.80),
    "background": (1.0, 1.0, 1.0),
    "strobe_first": (0.90, 0.92, 0.95),
    "strobe_last": (0.38, 0.46, 0.60),
}


# ----------------------------------------------------------------------------- validation


def _check_keypose(joints, keypose, keypose_frame):
    """(22, 3) keypose or None; ``keypose=None`` with a frame takes ``joints[keypose_frame]``."""
    T = len(joints)
    if keypose_frame is not None:
        if not float(keypose_frame).is_integer() or not -T <= int(keypose_frame) < T:
            raise ValueError(f"keypose_frame must be an integer frame index in 0..{T - 1}, got "
                             f"{keypose_frame}")
        keypose_frame = int(keypose_frame) % T
    if keypose is None:
        return (None if keypose_frame is None else joints[keypose_frame]), keypose_frame
    k = np.asarray(keypose, dtype=float)
    if k.shape != (_J, 3):
        raise ValueError(f"keypose must have shape ({_J}, 3), got {k.shape}")
    if not np.all(np.isfinite(k)):
        raise ValueError("keypose contains NaN or inf; give all 22 joints")
    return k, keypose_frame


def _check_trajectories(trajectories):
    """dict name/index -> (n, 3) float with NaN rows allowed -> list of (joint, points)."""
    if trajectories is None:
        return []
    if not isinstance(trajectories, dict):
        raise TypeError(f"trajectories must be a dict joint name -> (t_r, 3) array, got "
                         f"{type(trajectories).__name__}")
    out = []
    for key, pts in trajectories.items():
        if isinstance(key, str):
            j = joint_index(key)
        elif isinstance(key, (int, np.integer)) and 0 <= key < _J:
            j = int(key)
        else:
            raise ValueError(f"unknown trajectory joint {key!r}; use a name of {JOINT_NAMES} "
                             f"or an index 0..{_J - 1}")
        p = np.asarray(pts, dtype=float)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"trajectory of {JOINT_NAMES[j]} must have shape (t_r, 3) or "
                             f"(T, 3) with NaN rows for gaps, got {p.shape}")
        if np.any(np.isinf(p)):
            raise ValueError(f"trajectory of {JOINT_NAMES[j]} contains inf")
        if not np.any(np.all(np.isfinite(p), axis=1)):
            raise ValueError(f"trajectory of {JOINT_NAMES[j]} has no finite point")
        out.append((j, p))
    return out


def _runs(p):
    """Consecutive finite rows of ``p`` (n, 3): list of (m, 3) arrays (NaN rows split)."""
    ok = np.all(np.isfinite(p), axis=1)
    edges = np.flatnonzero(np.diff(np.r_[0, ok.astype(int), 0]))
    return [p[a:b] for a, b in zip(edges[::2], edges[1::2])]


def _check_size(size):
    w, h = (int(v) for v in size)
    if w < 16 or h < 16:
        raise ValueError(f"size must be (width, height) in pixels, each >= 16, got {size}")
    return w, h


def _prepare(joints, keypose, keypose_frame, trajectories, size, radius):
    x = _check_joints(joints)
    keypose, keypose_frame = _check_keypose(x, keypose, keypose_frame)
    trajs = _check_trajectories(trajectories)
    return x, keypose, keypose_frame, trajs, _check_size(size), _radii(radius)


def _frame_indices(frames, T):
    if frames is None:
        return np.arange(T), False
    if np.ndim(frames) == 0:
        idx = np.array([frames])
        single = True
    else:
        idx, single = np.asarray(frames).reshape(-1), False
    if idx.size == 0 or not np.all(np.mod(idx, 1) == 0) or np.any((idx < -T) | (idx >= T)):
        raise ValueError(f"frames must be None, a frame index or indices in 0..{T - 1}, got "
                         f"{frames!r}")
    return idx.astype(int) % T, single


# ----------------------------------------------------------------------------- ground


def _ground_height(x, radius, ground):
    """``"auto"`` / None: the lowest capsule point over the clip ``x`` (T, 22, 3), so the
    capsule human stands on the plane; else ``float(ground)``."""
    if ground is None or (isinstance(ground, str) and ground == "auto"):
        a, b, r, _ = capsule_segments(x, radius)
        return float((np.minimum(a[..., 1], b[..., 1]) - r).min())
    if isinstance(ground, str) or not np.isfinite(float(ground)):
        raise ValueError(f"ground must be 'auto', None or a height in metres, got {ground!r}")
    return float(ground)


def _ground_extent(points, cell=0.5, margin=0.75):
    """Square-snapped xz extent ``(x0, x1, z0, z1)`` covering ``points`` (..., 3)."""
    p = np.asarray(points).reshape(-1, 3)
    lo = np.floor((p[:, [0, 2]].min(0) - margin) / cell) * cell
    hi = np.ceil((p[:, [0, 2]].max(0) + margin) / cell) * cell
    return lo[0], hi[0], lo[1], hi[1]


# ----------------------------------------------------------------------------- strobe ghosts


def _strobe_indices(T, every, keypose_frame):
    if not float(every).is_integer() or every < 1:
        raise ValueError(f"every must be an integer >= 1 (frames between ghosts), got {every}")
    idx = list(range(0, T, int(every)))
    if idx[-1] != T - 1:
        idx.append(T - 1)
    if keypose_frame is not None and keypose_frame not in idx:
        idx = sorted(idx + [keypose_frame])
    return np.array(idx)


def _strobe_colors(n):
    w = np.linspace(0, 1, n)[:, None] if n > 1 else np.ones((1, 1))
    return (1 - w) * np.array(COLORS["strobe_first"]) + w * np.array(COLORS["strobe_last"])
