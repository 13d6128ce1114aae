"""Energy strokes: polylines that carry flow particles across the canvas (PhysAnimator
supp. Sec. 2, Figs. 1 and 6).

A stroke is drawn as a polyline ``points`` (k, 2) in pixels. Its particles start at the
first point at ``start`` seconds and travel along the polyline at ``speed`` px/s; a wind
particle blows along the stroke's tangent where it is (``d`` = unit tangent, Eq. 8) unless a
fixed ``direction`` is given. With ``n_particles > 1`` the particles follow each other at equal
spacing in time; with ``loop=True`` they start over when they reach the end, so the stroke
keeps blowing. A particle off the end of the stroke exerts nothing.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from physlab import _check

from .flow import FLOW_KINDS, _flow_force
from .rigging import MAX_COORD, _unit

__all__ = ["EnergyStroke"]


@dataclass
class EnergyStroke:
    """One energy stroke.

    points : (k, 2) polyline in pixels (k >= 2); kind : "wind" | "repel" | "attract";
    strength : s (force per vertex); range : r (px); speed : px/s along the stroke;
    start : s (time the first particle leaves); n_particles : particles on the stroke;
    loop : restart particles at the beginning; direction : optional fixed wind direction.
    """

    points: np.ndarray
    kind: str = "wind"
    strength: float = 1e4
    range: float = 60.0
    speed: float = 300.0
    start: float = 0.0
    n_particles: int = 1
    loop: bool = False
    direction: tuple | None = None
    _cum: np.ndarray = field(init=False, repr=False)
    _unit: np.ndarray | None = field(init=False, repr=False, default=None)

    def __post_init__(self):
        try:
            self.points = np.asarray(self.points, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"stroke points must be a (k, 2) list of numbers, got "
                             f"{self.points!r:.80}") from None
        if self.points.ndim != 2 or self.points.shape[1] != 2 or len(self.points) < 2:
            raise ValueError(f"stroke points must have shape (k >= 2, 2), got {self.points.shape}")
        if not isinstance(self.kind, str) or self.kind not in FLOW_KINDS:
            raise ValueError(f"unknown stroke kind {self.kind!r}; valid kinds are: {', '.join(FLOW_KINDS)}")
        if not np.all(np.isfinite(self.points)):
            k = int(np.flatnonzero(~np.isfinite(self.points).all(1))[0])
            raise ValueError(f"stroke points must be finite, point {k} is "
                             f"{self.points[k].tolist()}")
        if np.abs(self.points).max() > MAX_COORD:
            k = int(np.flatnonzero((np.abs(self.points) > MAX_COORD).any(1))[0])
            raise ValueError(f"stroke points must lie within ±{MAX_COORD:g} px, point {k} is "
                             f"{self.points[k].tolist()}")
        self.strength = _check.number(self.strength, "stroke strength")
        self.range = _check.number(self.range, "stroke range (px)", lo=0, lo_open=True)
        self.speed = _check.number(self.speed, "stroke speed (px/s)", lo=0, lo_open=True)
        self.start = _check.number(self.start, "stroke start (s)")
        self.n_particles = _check.number(self.n_particles, "stroke n_particles", lo=1, hi=1000,
                                         integer=True)
        if not isinstance(self.loop, (bool, np.bool_)):
            raise TypeError(f"stroke loop must be True or False, got {self.loop!r}")
        if self.direction is not None:
            d = _check.vector(self.direction, "stroke direction")
            if not np.any(d):
                raise ValueError("stroke direction must be a non-zero vector (or None: along "
                                 "the stroke)")
            self.direction = tuple(d.tolist())
            self._unit = _unit(d, "stroke direction")
        seg = np.linalg.norm(np.diff(self.points, axis=0), axis=1)
        if seg.sum() <= 0:
            raise ValueError("stroke has zero length")
        self._cum = np.concatenate([[0.0], np.cumsum(seg)])

    @property
    def length(self):
        """Arc length of the polyline (px)."""
        return float(self._cum[-1])

    def particles(self, t):
        """Active particles at time ``t``: positions (m, 2) and unit directions (m, 2)."""
        travel = self.length / self.speed  # seconds to run the stroke once
        offsets = np.arange(self.n_particles) * travel / self.n_particles
        age = t - self.start - offsets
        if self.loop:
            age = np.where(age >= 0, np.mod(age, travel), age)
        active = (age >= 0) & (age <= travel)
        s = age[active] * self.speed  # arc length travelled
        seg = np.clip(np.searchsorted(self._cum, s, side="right") - 1, 0, len(self.points) - 2)
        p0, p1 = self.points[seg], self.points[seg + 1]
        u = (s - self._cum[seg]) / np.maximum(self._cum[seg + 1] - self._cum[seg], 1e-12)
        pos = p0 + u[:, None] * (p1 - p0)
        if self.direction is not None:
            d = np.broadcast_to(self._unit, pos.shape)
        else:
            d = p1 - p0
        d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
        return pos, d

    def forces(self, q, t):
        """Total force (n, 2) of the stroke's active particles on vertices ``q`` at time ``t``."""
        q = np.asarray(q, dtype=float)
        f = np.zeros_like(q)
        for p, d in zip(*self.particles(t)):
            f += _flow_force(self.kind, p, q, self.strength, self.range, d)  # Eqs. (8)–(9)
        return f

    def to_dict(self):
        out = {k: v for k, v in asdict(self).items() if not k.startswith("_")}
        out["points"] = self.points.tolist()
        return out
