"""Flow particles (PhysAnimator supp. Sec. 2, Eqs. 8–9, Fig. 1).

A flow particle at ``p`` (2,) pushes the mesh vertices ``q`` (n, 2) within its influence
range ``r``; vertices at distance ``>= r`` feel nothing. ``s`` is the particle's strength
(a force per vertex: mass·px/s² for meshes in pixels).

* wind, Eq. (8):    ``f = s (1 - |p - q| / r) d``  (``d``: the particle's unit direction)
* repel, Eq. (9):   ``f = s (q - p) / r``
* attract, Eq. (9): ``f = s (1 - |q - p| / r) (p - q) / |p - q|``
"""
from __future__ import annotations

import numpy as np

__all__ = ["wind_force", "repel_force", "attract_force", "FLOW_KINDS", "flow_force"]

FLOW_KINDS = ("wind", "repel", "attract")


def _prep(p, q, r):
    p = np.asarray(p, dtype=float).reshape(2)
    q = np.asarray(q, dtype=float)
    if q.ndim != 2 or q.shape[1] != 2:
        raise ValueError(f"q must have shape (n, 2), got {q.shape}")
    if not r > 0:
        raise ValueError(f"influence range r must be > 0, got {r}")
    diff = q - p  # (n, 2) from the particle to the vertices
    dist = np.linalg.norm(diff, axis=1)
    return diff, dist, dist < r


def wind_force(p, q, d, s, r):
    """Wind particle force on vertices ``q`` (n, 2) — Eq. (8); ``d`` is normalised here."""
    diff, dist, inside = _prep(p, q, r)
    d = np.asarray(d, dtype=float).reshape(2)
    nd = np.linalg.norm(d)
    d = d / nd if nd > 0 else d
    w = dist / r  # Eq. (8): w(p, q) = |p - q| / r
    return np.where(inside[:, None], s * (1 - w)[:, None] * d, 0.0)


def repel_force(p, q, s, r):
    """Repel particle force ``s (q - p) / r`` within range — Eq. (9)."""
    diff, dist, inside = _prep(p, q, r)
    return np.where(inside[:, None], s * diff / r, 0.0)


def attract_force(p, q, s, r):
    """Attract particle force ``s (1 - |q - p|/r) (p - q)/|p - q|`` within range — Eq. (9)."""
    diff, dist, inside = _prep(p, q, r)
    safe = np.where(dist > 0, dist, 1.0)
    f = s * (1 - dist / r)[:, None] * (-diff) / safe[:, None]
    return np.where((inside & (dist > 0))[:, None], f, 0.0)


def flow_force(kind, p, q, s, r, d=(1.0, 0.0)):
    """Dispatch on ``kind`` in :data:`FLOW_KINDS`."""
    if kind == "wind":
        return wind_force(p, q, d, s, r)
    if kind == "repel":
        return repel_force(p, q, s, r)
    if kind == "attract":
        return attract_force(p, q, s, r)
    raise ValueError(f"unknown flow particle kind {kind!r}; valid kinds are: {', '.join(FLOW_KINDS)}")
