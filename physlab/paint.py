"""Drawing helpers for the pictures physlab makes itself (sample drawings, procedural
characters): a premultiplied-alpha canvas, antialiased fills and strokes of signed distance
fields (SDFs, in pixels, negative inside), pen lines, simple shading, and the ink colour.

Pixel coordinates ``(x, y)`` are pixel centres, y down (DESIGN.md). numpy only.
"""
from __future__ import annotations

import numpy as np

__all__ = ["INK", "Canvas", "fill", "stroke", "circle_sdf", "ellipse_sdf", "box_sdf",
           "polygon_sdf", "lines", "shade"]

#: Near-black ink (RGB in [0, 1]).
INK = np.array([0.09, 0.07, 0.11])


class Canvas:
    """Premultiplied-alpha RGBA float canvas; layers are composited with "over"."""

    def __init__(self, size):
        self.size = size
        self.rgb = np.zeros((size, size, 3))  # premultiplied colour
        self.alpha = np.zeros((size, size))
        yy, xx = np.mgrid[0:size, 0:size].astype(np.float64)
        self.x, self.y = xx, yy  # pixel centres (x, y), y down

    def paint(self, coverage, color):
        """Composite ``color`` ((3,) or (H, W, 3), in [0, 1]) with per-pixel ``coverage`` (H, W)."""
        c = np.clip(coverage, 0.0, 1.0)[..., None]
        self.rgb = np.asarray(color) * c + self.rgb * (1 - c)
        self.alpha = c[..., 0] + self.alpha * (1 - c[..., 0])

    def image(self):
        a = self.alpha[..., None]
        rgb = np.where(a > 0, self.rgb / np.maximum(a, 1e-12), 0.0)
        out = np.concatenate([rgb, a], axis=-1)
        return np.round(np.clip(out, 0, 1) * 255).astype(np.uint8)


def fill(sdf):
    """Antialiased coverage of the region ``sdf < 0`` (sdf in px)."""
    return np.clip(0.5 - sdf, 0.0, 1.0)


def stroke(sdf, width):
    """Antialiased coverage of an outline of ``width`` px centred on ``sdf = 0``."""
    return np.clip(width / 2 + 0.5 - np.abs(sdf), 0.0, 1.0)


def circle_sdf(cv, cx, cy, r):
    return np.hypot(cv.x - cx, cv.y - cy) - r


def ellipse_sdf(cv, cx, cy, rx, ry):
    """Approximate ellipse SDF (exact on the axes; good enough for antialiasing)."""
    q = np.hypot((cv.x - cx) / rx, (cv.y - cy) / ry)
    return (q - 1.0) * min(rx, ry)


def box_sdf(cv, x0, y0, x1, y1):
    """Exact SDF of the axis-aligned box [x0, x1] × [y0, y1]."""
    cx, cy, hx, hy = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / 2, (y1 - y0) / 2
    dx, dy = np.abs(cv.x - cx) - hx, np.abs(cv.y - cy) - hy
    return np.hypot(np.maximum(dx, 0), np.maximum(dy, 0)) + np.minimum(np.maximum(dx, dy), 0)


def polygon_sdf(cv, poly):
    """Exact SDF of a simple polygon (k, 2); vectorised over pixels, loop over its k edges."""
    P = np.asarray(poly, dtype=float)
    d2 = np.full(cv.x.shape, np.inf)
    inside = np.zeros(cv.x.shape, bool)
    for (ax, ay), (bx, by) in zip(P, np.roll(P, -1, axis=0)):
        ex, ey = bx - ax, by - ay
        wx, wy = cv.x - ax, cv.y - ay
        t = np.clip((wx * ex + wy * ey) / (ex * ex + ey * ey), 0, 1)
        d2 = np.minimum(d2, (wx - t * ex) ** 2 + (wy - t * ey) ** 2)
        crosses = ((ay > cv.y) != (by > cv.y)) & (cv.x < ax + (cv.y - ay) * ex / (ey + 1e-300))
        inside ^= crosses  # even-odd rule
    return np.where(inside, -1.0, 1.0) * np.sqrt(d2)


def lines(cv, segments, width=1.0):
    """Coverage (H, W) of antialiased pen lines ``segments`` (s, 4) = (x0, y0, x1, y1) in px.

    Uses ``skimage.draw.line_aa`` (Xiaolin Wu); ``width`` > 1 thickens by a max filter.
    """
    from scipy.ndimage import maximum_filter
    from skimage.draw import line_aa

    cov = np.zeros(cv.x.shape)
    for x0, y0, x1, y1 in np.round(np.asarray(segments)).astype(int):
        rr, cc, val = line_aa(y0, x0, y1, x1)
        ok = (rr >= 0) & (rr < cv.size) & (cc >= 0) & (cc < cv.size)
        np.maximum.at(cov, (rr[ok], cc[ok]), val[ok])
    if width > 1:
        cov = maximum_filter(cov, size=int(round(width)))
    return cov


def shade(cv, cx, cy, radius, base, strength=0.35):
    """Flat colour with a soft light from the upper left: (H, W, 3) in [0, 1]."""
    lx, ly = -0.6, -0.8  # light direction (y down: from the top left)
    u = ((cv.x - cx) * lx + (cv.y - cy) * ly) / radius  # > 0 on the lit side
    k = 1.0 + strength * np.clip(u, -1, 1)
    return np.clip(np.asarray(base)[None, None] * k[..., None], 0, 1)
