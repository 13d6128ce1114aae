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

from physlab import _check

__all__ = ["wind_force", "repel_force", "attract_force", "FLOW_KINDS", "flow_force"]

FLOW_KINDS = ("wind", "repel", "attract")


def _check_args(p, q, s, r, d=None):
    """Public entry points check their arguments once (strokes call the unchecked kernels)."""
    p = _check.vector(p, "p (particle position)")
    try:
        q = np.asarray(q, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"q (vertices) must be an (n, 2) array of numbers, got "
                        f"{type(q).__name__}") from None
    if q.ndim != 2 or q.shape[1] != 2:
        raise ValueError(f"q (vertices) must have shape (n, 2), got {q.shape}")
    if not np.all(np.isfinite(q)):
        raise ValueError("q (vertices) must be finite; it contains NaN or inf")
    s = _check.number(s, "s (strength)")
    r = _check.number(r, "r (influence range, px)", lo=0, lo_open=True)
    if d is not None:
        d = _check.vector(d, "d (wind direction)")
        if not np.linalg.norm(d) > 0:
            raise ValueError(f"d (wind direction) must be a non-zero vector, got {d.tolist()}")
    return p, q, s, r, d


def _prep(p, q, r):
    diff = q - p  # (n, 2) from the particle to the vertices
    dist = np.linalg.norm(diff, axis=1)
    return diff, dist, dist < r


def _wind(p, q, d, s, r):
    diff, dist, inside = _prep(p, q, r)
    nd = np.linalg.norm(d)
    d = d / nd if nd > 0 else d
    w = dist / r  # Eq. (8): w(p, q) = |p - q| / r
    return np.where(inside[:, None], s * (1 - w)[:, None] * d, 0.0)


def _repel(p, q, s, r):
    diff, dist, inside = _prep(p, q, r)
    return np.where(inside[:, None], s * diff / r, 0.0)  # Eq. (9)


def _attract(p, q, s, r):
    diff, dist, inside = _prep(p, q, r)
    safe = np.where(dist > 0, dist, 1.0)
    f = s * (1 - dist / r)[:, None] * (-diff) / safe[:, None]  # Eq. (9)
    return np.where((inside & (dist > 0))[:, None], f, 0.0)


def wind_force(p, q, d, s, r):
    """Wind particle force on vertices ``q`` (n, 2) — Eq. (8); ``d`` (2,) non-zero, normalised
    here; ``s`` finite, ``r`` > 0 (px). Returns (n, 2)."""
    p, q, s, r, d = _check_args(p, q, s, r, d)
    return _wind(p, q, d, s, r)


def repel_force(p, q, s, r):
    """Repel particle force ``s (q - p) / r`` within range — Eq. (9). Returns (n, 2)."""
    p, q, s, r, _ = _check_args(p, q, s, r)
    return _repel(p, q, s, r)


def attract_force(p, q, s, r):
    """Attract particle force ``s (1 - |q - p|/r) (p - q)/|p - q|`` within range — Eq. (9).
    Returns (n, 2)."""
    p, q, s, r, _ = _check_args(p, q, s, r)
    return _attract(p, q, s, r)


def _check_kind(kind):
    if not isinstance(kind, str) or kind not in FLOW_KINDS:
        raise ValueError(f"unknown flow particle kind {kind!r}; valid kinds are: "
                         f"{', '.join(FLOW_KINDS)}")
    return kind


def flow_force(kind, p, q, s, r, d=(1.0, 0.0)):
    """Dispatch on ``kind`` in :data:`FLOW_KINDS` (arguments checked as by the functions)."""
    _check_kind(kind)
    if kind == "wind":
        return wind_force(p, q, d, s, r)
    return repel_force(p, q, s, r) if kind == "repel" else attract_force(p, q, s, r)


def _flow_force(kind, p, q, s, r, d):
    """:func:`flow_force` without argument checks, for the time loop (an
    :class:`~physlab.physanimator.EnergyStroke` checks its parameters when built): ``p``
    (2,), ``q`` (n, 2), ``d`` (2,) float arrays."""
    if kind == "wind":
        return _wind(p, q, d, s, r)
    return _repel(p, q, s, r) if kind == "repel" else _attract(p, q, s, r)
