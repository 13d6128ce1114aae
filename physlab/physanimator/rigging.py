"""Rigging points (PhysAnimator supp. Sec. 2, Eq. 10): fixed regions and wavy rigs.

A rig selects vertices of one body — those within ``radius`` px of ``center`` in the rest
shape, or an explicit list — and drives them kinematically (their dynamics are overridden):

* :class:`FixedRig` pins them at their rest positions;
* :class:`WavyRig` moves them with the wavy rigging point of Eq. (10),
  ``x_r(t) = X_r + s sin(f t) d_r``: every selected vertex follows the rig point's offset
  ``s sin(f t) d_r`` (``f`` in rad/s, ``d_r`` normalised), with velocity ``s f cos(f t) d_r``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from physlab import _check

__all__ = ["FixedRig", "WavyRig", "wavy_rig_position"]


#: Largest coordinate (px) of a rig centre, stroke point or body vertex on the canvas: far
#: beyond any canvas (at most 16384 px), small enough that squared distances cannot overflow.
MAX_COORD = 1e7


def _unit(d, name):
    """The finite, non-zero 2-vector ``d`` scaled to length 1 (no overflow for huge ``d``)."""
    d = _check.vector(d, name)
    big = float(np.abs(d).max())
    if not big > 0:
        raise ValueError(f"{name} must be a non-zero vector, got {d.tolist()}")
    d = d / big
    return d / np.linalg.norm(d)


def wavy_rig_position(X_r, s, f, d_r, t):
    """Eq. (10): ``x_r(t) = X_r + s sin(f t) d_r`` (``X_r`` (..., 2) px; amplitude ``s`` px,
    frequency ``f`` rad/s, ``t`` s; ``d_r`` (2,) is normalised here and must be non-zero)."""
    d = _unit(d_r, "d_r (direction)")
    return np.asarray(X_r, dtype=float) + s * np.sin(f * t) * d  # Eq. (10)


@dataclass
class FixedRig:
    """Pin the vertices of body ``body`` within ``radius`` of ``center`` (or ``vertices``)."""

    body: int = 0
    center: tuple | None = None
    radius: float | None = None
    vertices: tuple | None = None

    def __post_init__(self):
        kind = type(self).__name__
        self.body = _check.number(self.body, f"{kind} body (index)", lo=0, integer=True)
        if self.center is not None:
            c = _check.vector(self.center, f"{kind} center")
            if np.abs(c).max() > MAX_COORD:
                raise ValueError(f"{kind} center must lie within ±{MAX_COORD:g} px, got "
                                 f"{c.tolist()}")
            self.center = tuple(c.tolist())
        if self.radius is not None:
            self.radius = _check.number(self.radius, f"{kind} radius (px)", lo=0, lo_open=True)
        if self.vertices is not None:
            v = np.asarray(self.vertices)
            if v.ndim != 1 or (v.size and not np.issubdtype(v.dtype, np.integer)):
                raise ValueError(f"{kind} vertices must be a list of vertex indices, got "
                                 f"{self.vertices!r}")
            if v.size == 0:
                raise ValueError(f"{kind} vertices is empty: list the vertex indices to rig, or "
                                 f"pass center and radius instead")
            if v.min() < 0:
                raise ValueError(f"{kind} vertices must be indices >= 0, got {int(v.min())}")
            self.vertices = tuple(int(i) for i in v)
        if self.vertices is None and (self.center is None or self.radius is None):
            raise ValueError(f"{kind} needs either vertices or center and radius")

    def select(self, X):
        """Indices (k,) of the rigged vertices of a body with rest positions ``X`` (n, 2)."""
        if self.vertices is not None:
            idx = np.unique(np.asarray(self.vertices, dtype=int))
            if idx.size == 0:
                raise ValueError("a rig with an empty vertex list selects nothing")
            if idx.min() < 0 or idx.max() >= len(X):
                bad = int(idx[(idx < 0) | (idx >= len(X))][0])
                raise ValueError(f"rig vertex {bad} is outside 0..{len(X) - 1} (the body has "
                                 f"{len(X)} vertices)")
            return idx
        if self.center is None or self.radius is None:
            raise ValueError("a rig needs either vertices or center and radius")
        idx = np.flatnonzero(np.linalg.norm(X - np.asarray(self.center, float), axis=1) <= self.radius)
        if idx.size == 0:
            raise ValueError(f"rig at {self.center} with radius {self.radius} selects no vertex; "
                             "move it onto the body or enlarge the radius")
        return idx

    def offset(self, t):
        """Displacement (2,) and velocity (2,) of the rigged vertices at time ``t``."""
        return np.zeros(2), np.zeros(2)

    def to_dict(self):
        return {"type": type(self).__name__,
                **{k: (np.asarray(v).tolist() if isinstance(v, (tuple, list, np.ndarray)) else v)
                   for k, v in self.__dict__.items()}}


@dataclass
class WavyRig(FixedRig):
    """Wavy rigging point, Eq. (10): amplitude ``s`` (px), frequency ``f`` (rad/s),
    direction ``d_r``; the selected region follows ``s sin(f t) d_r``."""

    amplitude: float = 20.0
    frequency: float = 2 * np.pi
    direction: tuple = (1.0, 0.0)

    def __post_init__(self):
        super().__post_init__()
        self.amplitude = _check.number(self.amplitude, "WavyRig amplitude (px)")
        self.frequency = _check.number(self.frequency, "WavyRig frequency (rad/s)")
        _unit(self.direction, "WavyRig direction")
        self.direction = tuple(_check.vector(self.direction, "WavyRig direction").tolist())

    def offset(self, t):
        d = np.asarray(self.direction, dtype=float)
        d = d / np.abs(d).max()                     # no overflow for huge components
        d = d / np.linalg.norm(d)
        disp = self.amplitude * np.sin(self.frequency * t) * d  # Eq. (10), checked once above
        vel = self.amplitude * self.frequency * np.cos(self.frequency * t) * d
        return disp, vel
