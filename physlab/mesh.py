"""Triangle meshes for 2D drawings: masks → outlines → quality triangulations, plus builders.

The PhysAnimator pipeline (and later the inbetweening code) turns a drawing into an elastic
body: a foreground **mask** is cut out of the image, its outer **boundary polygon** is traced
and simplified, and the polygon is filled with a **conforming constrained Delaunay
triangulation** with an angle bound (Shewchuk's Triangle, via the ``triangle`` package), so
that the linear FEM of :mod:`physlab.fem` sees well-shaped elements.

Coordinates and orientation
---------------------------
Meshes built from images live in **pixel coordinates** ``(x, y)`` with ``y`` pointing
**down** (DESIGN.md): pixel ``image[i, j]`` (row ``i``, column ``j``) has its centre at
``(x, y) = (j, i)``.

A triangle ``(i0, i1, i2)`` is **positively oriented** when its signed area ::

    area = 0.5 * ((x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0))          # Eq. (A)

is > 0, i.e. ``det [X1 - X0, X2 - X0] > 0`` (the ``Dm`` of PhysAnimator supp. Eq. (6)).
This is counter-clockwise when the axes are drawn the mathematical way (y up, e.g.
``plt.triplot`` without inverting the axis); on an image displayed with y down (``imshow``)
the same triangle looks clockwise. Every builder in this module returns positively oriented
triangles, and polygons returned by :func:`boundary_polygon` have positive shoelace area
(Eq. (A) summed over a fan), i.e. they run the same way round.

References
----------
[Tri] J. R. Shewchuk, "Triangle: Engineering a 2D quality mesh generator and Delaunay
    triangulator", WACG 1996 (constrained Delaunay + Ruppert refinement, switches ``pq a``).
[Otsu] N. Otsu, "A threshold selection method from gray-level histograms", IEEE SMC 1979.
[DP] D. Douglas, T. Peucker, "Algorithms for the reduction of the number of points required
    to represent a digitized line or its caricature", 1973.
[PA] PhysAnimator supplementary (``../shared/seeds/000_0a4fa540c2202b0e.txt``): the drawing
    is segmented, its outline triangulated, and simulated with linear FEM (Eqs. 1–7).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy import ndimage as ndi
from scipy.spatial import cKDTree

# scikit-image, triangle and matplotlib are imported inside the functions that use them, so
# ``import physlab.mesh`` stays cheap for code that only needs TriMesh and the builders.

__all__ = [
    "TriMesh",
    "triangle_areas",
    "triangle_angles",
    "foreground_mask",
    "mask_from_array",
    "fill_small_holes",
    "mask_components",
    "boundary_polygon",
    "boundary_loops",
    "polygon_area",
    "polygon_is_simple",
    "loops_are_disjoint",
    "remove_sharp_corners",
    "chamfer_corners",
    "triangulate_polygon",
    "default_max_area",
    "mesh_from_mask",
    "meshes_from_image",
    "grid_mesh",
    "polygon_mesh",
    "disk_mesh",
    "strip_mesh",
    "locate_points",
    "point_in_mesh",
    "vertex_indices",
]

#: Default number of triangles per polygon area used by :func:`default_max_area`.
TARGET_TRIANGLES = 300
#: Largest triangle count Triangle is asked for (area / max_area): more fails fast instead of
#: running for minutes and filling memory.
MAX_TRIANGLES = 2_000_000
#: Largest relative difference between a mask's area and its mesh's (:func:`mesh_from_mask`).
AREA_TOLERANCE = 0.10
#: Outline corners below this angle (degrees) are chamfered by :func:`mesh_from_mask`.
CHAMFER_ANGLE = 60.0
#: Smallest default area bound (px²) of :func:`mesh_from_mask`: finer than a few pixels
#: per triangle adds nothing for an image.
MIN_PIXEL_AREA = 12.0
#: Holes of a mask with fewer pixels are filled (:func:`fill_small_holes`): scan speckles and
#: antialiasing pinholes, not the gaps a figure is drawn with (a 4×4 px gap is kept).
MIN_HOLE_AREA = 16


# ---------------------------------------------------------------------------------- geometry
def triangle_areas(X, tris):
    """Signed triangle areas, Eq. (A) of the module docstring.

    Parameters
    ----------
    X : (n, 2) float array, vertex positions (pixels, or any length unit).
    tris : (T, 3) int array, vertex indices.

    Returns
    -------
    (T,) float64, ``0.5 ((x1-x0)(y2-y0) - (x2-x0)(y1-y0))`` in units², > 0 for positively
    oriented triangles.
    """
    X = np.asarray(X, dtype=float)
    tris = np.asarray(tris)
    p0, p1, p2 = X[tris[:, 0]], X[tris[:, 1]], X[tris[:, 2]]
    e1, e2 = p1 - p0, p2 - p0
    return 0.5 * (e1[:, 0] * e2[:, 1] - e2[:, 0] * e1[:, 1])  # Eq. (A)


def triangle_angles(X, tris):
    """Interior angles of every triangle.

    Returns
    -------
    (T, 3) float64, degrees; column ``k`` is the angle at vertex ``tris[:, k]``. Each row
    sums to 180 for non-degenerate triangles. ``triangle_angles(X, tris).min()`` is the mesh's
    minimum angle, the quality measure Triangle's ``q`` switch bounds from below.
    """
    X = np.asarray(X, dtype=float)
    tris = np.asarray(tris)
    P = X[tris]  # (T, 3, 2)
    a = np.roll(P, -1, axis=1) - P  # (T, 3, 2) edge to the next vertex
    b = np.roll(P, 1, axis=1) - P  # (T, 3, 2) edge to the previous vertex
    cross = np.abs(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0])
    dot = np.einsum("tkd,tkd->tk", a, b)
    return np.degrees(np.arctan2(cross, dot))


def polygon_area(polygon):
    """Signed area of a closed polygon (shoelace), > 0 for the positive orientation.

    Parameters
    ----------
    polygon : (k, 2) float array of vertices ``(x, y)``, without a repeated closing vertex.

    Returns
    -------
    float, ``0.5 Σ (x_i y_{i+1} - x_{i+1} y_i)`` — Eq. (A) summed over a fan of triangles.
    """
    P = np.asarray(polygon, dtype=float)
    Q = np.roll(P, -1, axis=0)
    return 0.5 * float(np.sum(P[:, 0] * Q[:, 1] - Q[:, 0] * P[:, 1]))


def _orient(a, b, c):
    """Twice the signed area of triangles (a, b, c); arrays broadcast over leading axes."""
    ab, ac = b - a, c - a
    return ab[..., 0] * ac[..., 1] - ac[..., 0] * ab[..., 1]


def polygon_is_simple(polygon, chunk=256):
    """True when no two non-adjacent edges of the closed polygon touch or cross.

    O(k²) segment-pair test, vectorised in blocks of ``chunk`` edges (fine for the few
    hundred vertices of a simplified outline).
    """
    P = np.asarray(polygon, dtype=float)
    if len(P) < 3:
        return False
    return loops_are_disjoint([P], chunk=chunk)


def loops_are_disjoint(loops, chunk=256):
    """True when the closed polygons ``loops`` are simple and no two of them touch or cross.

    The test a planar straight-line graph of an outline and its holes must pass before
    Triangle meshes it: no two edges meet, except consecutive edges of one loop at their
    shared vertex. O(k²) in the total vertex count ``k``, vectorised in blocks of ``chunk``
    edges.

    Parameters
    ----------
    loops : list of (k_i, 2) float polygons, each closed implicitly (no repeated vertex).

    Returns
    -------
    bool; :func:`polygon_is_simple` is ``loops_are_disjoint([polygon])``.
    """
    loops = [np.asarray(L, dtype=float) for L in loops]
    A = np.concatenate(loops)  # edge e runs A[e] -> B[e]
    B = np.concatenate([np.roll(L, -1, axis=0) for L in loops])
    sizes = np.array([len(L) for L in loops])
    loop = np.repeat(np.arange(len(loops)), sizes)  # (k,) loop of each edge
    pos = np.concatenate([np.arange(m) for m in sizes])  # (k,) index within its loop
    size = sizes[loop]
    lo, hi = np.minimum(A, B), np.maximum(A, B)
    for s in range(0, len(A), chunk):
        a, b = A[s:s + chunk, None], B[s:s + chunk, None]  # (c, 1, 2)
        c, d = A[None], B[None]  # (1, k, 2)
        o1, o2 = _orient(a, b, c), _orient(a, b, d)
        o3, o4 = _orient(c, d, a), _orient(c, d, b)
        lo_s, hi_s = lo[s:s + chunk, None], hi[s:s + chunk, None]
        boxes = np.all((lo_s <= hi[None]) & (lo[None] <= hi_s), axis=-1)
        hit = (o1 * o2 <= 0) & (o3 * o4 <= 0) & boxes
        gap = np.abs(pos[s:s + chunk, None] - pos[None])
        adjacent = (loop[s:s + chunk, None] == loop[None]) & (
            (gap <= 1) | (gap == size[s:s + chunk, None] - 1))
        if np.any(hit & ~adjacent):
            return False
    return True


def _compact(X, tris):
    """Drop vertices no triangle uses; returns ``(X, tris)`` re-indexed."""
    used = np.zeros(len(X), bool)
    used[tris.ravel()] = True
    if used.all():
        return X, tris
    new_index = np.cumsum(used) - 1
    return X[used], new_index[tris]


def _orient_positive(X, tris):
    """Swap two indices of every negatively oriented triangle."""
    tris = tris.copy()
    neg = triangle_areas(X, tris) < 0
    tris[neg, 1], tris[neg, 2] = tris[neg, 2], tris[neg, 1].copy()
    return tris


# ---------------------------------------------------------------------------------- TriMesh
@dataclass(frozen=True, eq=False)
class TriMesh:
    """A 2D triangle mesh: rest positions and triangles (immutable).

    Attributes
    ----------
    X : (n, 2) float64, rest positions (pixels for meshes built from images; y down).
        Stored read-only; copy it (``x = mesh.X.copy()``) to get current positions.
    tris : (T, 3) int64, vertex indices. Builders of this module return positively
        oriented triangles (area Eq. (A) > 0, see the module docstring); the class itself
        accepts either orientation and :attr:`areas` is signed.

    Construction checks shapes, finiteness, index range, and rejects degenerate triangles
    (``|area| <= 1e-12 * scale²``, ``scale`` = largest extent of ``X``) with a ValueError that
    names the first offending triangle.
    """

    X: np.ndarray
    tris: np.ndarray

    def __post_init__(self):
        X = np.array(self.X, dtype=np.float64)
        if X.ndim != 2 or X.shape[1] != 2:
            raise ValueError(f"X must have shape (n, 2), got {X.shape}")
        if not np.all(np.isfinite(X)):
            raise ValueError("X contains NaN or inf; vertex positions must be finite")
        tris = np.array(self.tris)
        if tris.ndim != 2 or tris.shape[1] != 3:
            raise ValueError(f"tris must have shape (T, 3), got {tris.shape}")
        if len(tris) == 0:
            raise ValueError("a TriMesh needs at least one triangle, got tris of shape (0, 3)")
        if not np.issubdtype(tris.dtype, np.integer):
            if not (np.issubdtype(tris.dtype, np.floating) and np.all(np.mod(tris, 1) == 0)):
                raise ValueError(f"tris must hold integer vertex indices, got dtype {tris.dtype}")
        tris = tris.astype(np.int64)
        if tris.min() < 0 or tris.max() >= len(X):
            t = int(np.flatnonzero(((tris < 0) | (tris >= len(X))).any(1))[0])
            raise ValueError(f"triangle {t} {tris[t].tolist()} refers to a vertex that does not "
                             f"exist (valid indices 0..{len(X) - 1})")
        key = np.sort(tris, axis=1)
        _, first, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
        if (counts > 1).any():
            dup = np.flatnonzero(counts > 1)
            t = int(first[dup[0]])
            raise ValueError(f"{int((counts[dup] - 1).sum())} duplicate triangle(s): triangle {t} "
                             f"{tris[t].tolist()} appears {int(counts[dup[0]])} times (with any "
                             f"vertex order); remove duplicates, e.g. with np.unique(np.sort(tris, "
                             f"axis=1), axis=0)")
        if np.abs(X).max(initial=0.0) > 1e100:
            raise ValueError(f"X has coordinates up to {np.abs(X).max():.3g}; vertex "
                             f"positions must be below 1e100 (areas would overflow)")
        area = triangle_areas(X, tris)
        scale = float(np.ptp(X[tris.ravel()], axis=0).max())
        bad = np.flatnonzero(np.abs(area) <= 1e-12 * scale**2)
        if bad.size:
            t = int(bad[0])
            raise ValueError(
                f"{bad.size} degenerate (zero-area) triangle(s); the first is triangle {t} with "
                f"vertices {tris[t].tolist()} at {X[tris[t]].tolist()}. Remove them (e.g. "
                f"tris[np.abs(triangle_areas(X, tris)) > tol]) or re-mesh")
        X.setflags(write=False)
        tris.setflags(write=False)
        object.__setattr__(self, "X", X)
        object.__setattr__(self, "tris", tris)

    def __repr__(self):
        return f"TriMesh(n={self.n}, n_tris={self.n_tris}, area={self.area:.6g})"

    @property
    def n(self):
        """Number of vertices."""
        return len(self.X)

    @property
    def n_tris(self):
        """Number of triangles ``T``."""
        return len(self.tris)

    @cached_property
    def areas(self):
        """(T,) float64 signed areas, Eq. (A) (units²; > 0 for positive orientation)."""
        a = triangle_areas(self.X, self.tris)
        a.setflags(write=False)
        return a

    @property
    def area(self):
        """Total unsigned area (units²)."""
        return float(np.abs(self.areas).sum())

    @property
    def is_positively_oriented(self):
        """True when every triangle has positive signed area (Eq. (A))."""
        return bool(np.all(self.areas > 0))

    def angles(self):
        """(T, 3) interior angles in degrees (see :func:`triangle_angles`)."""
        return triangle_angles(self.X, self.tris)

    def min_angle(self):
        """Smallest interior angle of the mesh (degrees)."""
        return float(self.angles().min())

    def _directed_edges(self):
        t = self.tris
        return np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])  # (3T, 2)

    def edges(self):
        """(E, 2) int64 unique undirected edges, each stored ``(i, j)`` with ``i < j``, sorted."""
        return np.unique(np.sort(self._directed_edges(), axis=1), axis=0)

    def boundary_edges(self):
        """(B, 2) int64 boundary edges (edges of exactly one triangle), oriented as in that triangle.

        For a positively oriented mesh, the outer boundary then runs the positive way round
        (interior on the left with y drawn up) and hole boundaries the other way.
        """
        d = self._directed_edges()
        _, inverse, counts = np.unique(np.sort(d, axis=1), axis=0, return_inverse=True,
                                       return_counts=True)
        return d[counts[inverse.ravel()] == 1]

    def boundary_vertices(self):
        """(b,) int64 sorted indices of the vertices on the boundary."""
        return np.unique(self.boundary_edges())

    def oriented(self):
        """A copy with every triangle positively oriented (Eq. (A) > 0)."""
        return TriMesh(self.X, _orient_positive(self.X, self.tris))

    @cached_property
    def _trifinder(self):
        from matplotlib.tri import Triangulation, TrapezoidMapTriFinder
        return TrapezoidMapTriFinder(Triangulation(self.X[:, 0], self.X[:, 1], self.tris))


# ---------------------------------------------------------------------------------- masks
def _as_float_image(image):
    """(H, W[, C]) uint8 / uint16 / float image → float64 in [0, 1] (:func:`physlab.image.
    as_float`)."""
    from physlab.image import as_float

    if np.asarray(image).dtype == bool:
        raise ValueError("got a boolean array; foreground_mask expects an image — pass a "
                         "ready-made mask through mask_from_array(m) instead")
    return as_float(image, dtype=np.float64)


def _disk(radius):
    r = int(radius)
    yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
    return xx**2 + yy**2 <= radius**2  # same footprint as skimage.morphology.disk


def _remove_small(mask, min_area):
    """Drop 4-connected components with fewer than ``min_area`` pixels."""
    if min_area <= 1:
        return mask
    labels, _ = ndi.label(mask)
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    return (sizes >= min_area)[labels]


def _hole_labels(mask):
    """Holes of a mask: ``(labels (H, W) int, sizes (n + 1,) int)``.

    A hole is a connected region of background pixels that does not reach the image border,
    with background pixels **8-connected** (the foreground 4-connected: the convention of
    ``ndi.label`` on the foreground and of marching squares' contours, so every hole found
    here is a hole contour of :func:`boundary_loops`). ``labels`` is 0 off the holes and
    1..n on them; ``sizes[0] = 0``.
    """
    bg = np.pad(~mask, 1, constant_values=True)  # the padding joins every outer region
    labels, n = ndi.label(bg, structure=np.ones((3, 3), bool))
    labels[labels == labels[0, 0]] = 0  # the outside is no hole
    labels = labels[1:-1, 1:-1]
    sizes = np.bincount(labels.ravel(), minlength=n + 1)
    sizes[0] = 0
    return labels, sizes


def fill_small_holes(mask, min_hole_area=None):
    """Fill the holes of a mask that have fewer than ``min_hole_area`` pixels.

    Holes are background regions enclosed by the foreground (8-connected background, see
    :func:`boundary_loops`): pinholes of a scan or of antialiasing are filled, real gaps (the
    white between an arm and the torso) are kept.

    Parameters
    ----------
    mask : (H, W) mask (anything :func:`mask_from_array` accepts).
    min_hole_area : float px ≥ 0, default :data:`MIN_HOLE_AREA` (16 px, a 4×4 gap); 0 fills
        nothing, ``np.inf`` fills every hole.

    Returns
    -------
    (H, W) bool, a new array.
    """
    min_hole_area = _check_min_hole_area(min_hole_area)
    m = mask_from_array(mask)
    labels, sizes = _hole_labels(m)
    small = sizes < min_hole_area
    small[0] = False
    return m | small[labels]


def _check_min_hole_area(min_hole_area):
    """``min_hole_area`` as a float ≥ 0 (None: :data:`MIN_HOLE_AREA`); ValueError otherwise."""
    if min_hole_area is None:
        return float(MIN_HOLE_AREA)
    try:
        a = float(min_hole_area)
    except (TypeError, ValueError):
        a = float("nan")
    if not a >= 0:  # also NaN
        raise ValueError(f"min_hole_area must be a number of px >= 0 (np.inf fills every "
                         f"hole), got {min_hole_area!r}")
    return a


def _close_and_dilate(mask, close_radius, dilate_radius):
    """Morphological closing, then dilation, with disks (px); the image border stays open."""
    pad = int(max(close_radius, dilate_radius, 0)) + 1
    m = np.pad(mask, pad)  # zero border: closing must not glue the drawing to the image edge
    if close_radius > 0:
        m = ndi.binary_closing(m, structure=_disk(close_radius))
    if dilate_radius > 0:
        m = ndi.binary_dilation(m, structure=_disk(dilate_radius))
    return m[pad:-pad, pad:-pad]


def foreground_mask(image, threshold=None, close_radius=2, fill_holes=None, min_area=64,
                    use_alpha=True, dilate_radius=None, min_hole_area=None):
    """Foreground (drawing) mask of an image: the pixels that belong to the drawn bodies.

    Two sources of "foreground":

    * **alpha** — when the image has an alpha channel that is not fully opaque (and
      ``use_alpha``): ``alpha > 0.5``;
    * **ink on paper** — otherwise: pixels *darker than a light background*, i.e. luminance
      ``L = 0.2125 R + 0.7154 G + 0.0721 B`` (ITU-R BT.709, as ``skimage.color.rgb2gray``)
      below ``threshold``; by default the threshold is Otsu's [Otsu], which separates the
      bimodal ink/paper histogram by maximising the between-class variance.

    The raw mask is then cleaned: a morphological closing with a disk of ``close_radius`` px
    bridges small gaps in the outline; a dilation with a disk of ``dilate_radius`` px grows
    the mask so that it encloses the whole (antialiased) ink stroke and closes gaps of up to
    about twice that width — like the AnimatedDrawings masks, which are closed and dilated by
    2 px; holes are filled or kept (``fill_holes``); 4-connected components smaller than
    ``min_area`` px are removed.

    Holes (``fill_holes``). A hole is background enclosed by the figure
    (:func:`fill_small_holes`); holes of fewer than ``min_hole_area`` px (speckles) are always
    filled. By default (``None``) the holes that are certainly real are kept — on the alpha
    path, where a transparent region inside the figure (the gap between an arm bent to the
    hip and the torso) is not part of it; :func:`mesh_from_mask` then meshes it as a hole.
    On the ink path holes are filled by default, as in the AnimatedDrawings masks: a region
    lighter than the ink inside the figure is the unpainted inside of an outline drawing,
    a white eye or highlight, or a gap, and its colour cannot tell which (measured: a
    bare-paper test turned the insides of char2 and char4 and the white spots of the sample
    ball and jelly into holes); pass ``fill_holes=False`` to keep them.

    ``fill_holes=True`` fills every hole on both paths (``scipy.ndimage.binary_fill_holes``,
    the behaviour before holes were kept); ``False`` keeps every hole of at least
    ``min_hole_area`` px on both paths.

    Parameters
    ----------
    image : (H, W), (H, W, 3) or (H, W, 4) array, uint8 in 0..255 or float in [0, 1].
    threshold : None or float in (0, 1], luminance threshold (default Otsu).
    close_radius : int >= 0, px.
    fill_holes : None (keep the holes of the alpha path, fill those of the ink path), True
        (fill all) or False (keep all).
    min_area : int, px.
    use_alpha : bool, use a non-opaque alpha channel when present.
    dilate_radius : None or int >= 0, px. Default: 2 for the ink path (thin pen strokes
        with gaps; measured on the six AnimatedDrawings characters it raises the IoU with
        their masks from 0.11–0.95 to 0.87–0.99), 0 for the alpha path (alpha is exact).
    min_hole_area : None (:data:`MIN_HOLE_AREA` = 16 px) or float px >= 0, holes with fewer
        pixels are filled whatever ``fill_holes`` says.

    Returns
    -------
    (H, W) bool mask.

    Assumes dark drawings on a light background; for a light drawing on a dark background
    pass ``1 - image`` (float) or ``255 - image`` (uint8 RGB).
    """
    img = _as_float_image(image)
    if close_radius < 0 or (dilate_radius is not None and dilate_radius < 0) or min_area < 0:
        raise ValueError("close_radius, dilate_radius and min_area must be >= 0")
    if fill_holes is not None and not isinstance(fill_holes, (bool, np.bool_)):
        raise ValueError(f"fill_holes must be None (keep the holes of a transparent image's "
                         f"figure), True (fill every hole) or False (keep every hole), got "
                         f"{fill_holes!r}")
    min_hole_area = _check_min_hole_area(min_hole_area)
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[..., 0]
    alpha = img[..., 3] if img.ndim == 3 and img.shape[2] == 4 else None
    use_alpha = use_alpha and alpha is not None and np.any(alpha < 1.0)
    if use_alpha:
        raw = alpha > 0.5
        dilate = 0 if dilate_radius is None else dilate_radius
    else:
        if img.ndim == 3:
            rgb = img[..., :3]
            lum = rgb @ np.array([0.2125, 0.7154, 0.0721])
        else:
            lum = img
        if threshold is None:
            if np.ptp(lum) < 1e-6:  # a blank page: no ink anywhere
                return np.zeros(lum.shape, bool)
            from skimage.filters import threshold_otsu
            threshold = threshold_otsu(lum)
        elif not 0 < threshold <= 1:
            raise ValueError(f"threshold is a luminance in (0, 1], got {threshold}")
        raw = lum < threshold
        dilate = 2 if dilate_radius is None else dilate_radius
    m = _close_and_dilate(raw, close_radius, dilate)
    if fill_holes or (fill_holes is None and not use_alpha):
        m = ndi.binary_fill_holes(m)
    else:
        m = fill_small_holes(m, min_hole_area)
    return _remove_small(m, min_area)


def mask_from_array(m):
    """A ready-made mask as a bool array.

    Parameters
    ----------
    m : (H, W) array — bool; integer 0/255 (``> 127``) or 0/1 (``> 0``); or float in [0, 1]
        (``> 0.5``). (H, W, C) arrays whose channels are all equal (a grey mask saved as RGB)
        are accepted too.

    Returns
    -------
    (H, W) bool, a new array.
    """
    a = np.asarray(m)
    if a.ndim == 3:
        if not np.all(a == a[..., :1]):
            raise ValueError(f"mask has {a.shape[2]} different channels; pass a single-channel mask "
                             "or use foreground_mask(image) for a colour image")
        a = a[..., 0]
    if a.ndim != 2:
        raise ValueError(f"mask must have shape (H, W), got {a.shape}")
    if a.dtype == bool:
        return a.copy()
    if np.issubdtype(a.dtype, np.integer):
        return a > (127 if a.max() > 1 else 0)
    if not np.all(np.isfinite(a)):
        raise ValueError("mask contains NaN or inf")
    return a > 0.5


def mask_components(mask, min_area=64):
    """Split a mask into its 4-connected components, largest first.

    Parameters
    ----------
    mask : (H, W) mask (anything :func:`mask_from_array` accepts).
    min_area : components with fewer pixels are dropped.

    Returns
    -------
    list of (H, W) bool masks, by decreasing pixel count (ties: lower label first).
    """
    mask = mask_from_array(mask)
    labels, n = ndi.label(mask)  # 4-connectivity, like find_contours' default on the foreground
    sizes = np.bincount(labels.ravel(), minlength=n + 1)[1:]
    order = np.argsort(-sizes, kind="stable")
    return [labels == (k + 1) for k in order if sizes[k] >= max(min_area, 1)]


def _largest_component(mask):
    labels, n = ndi.label(mask)
    if n == 0:
        raise ValueError("the mask is empty (no foreground pixels); check the image/threshold, "
                         "e.g. foreground_mask(image, threshold=...)")
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    return labels == np.argmax(sizes)


def _interior_angles(P):
    """(k,) interior angles (degrees) of a positively oriented polygon: < 180 convex."""
    e1 = P - np.roll(P, 1, axis=0)  # edge into vertex i
    e2 = np.roll(P, -1, axis=0) - P  # edge out of vertex i
    turn = np.arctan2(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0], np.einsum("kd,kd->k", e1, e2))
    return np.degrees(np.pi - turn)


def remove_sharp_corners(polygon, min_angle):
    """Cut off polygon corners whose interior angle is below ``min_angle`` degrees.

    Triangle cannot make a triangle's angles larger than the input angle between two
    boundary segments, so an outline with a needle-like spike would keep a sliver there.
    Each pass removes the spike vertices (not two neighbours in one pass); the removed area
    is the thin spike tip. Stops when no corner is sharper or 3 vertices are left.

    Parameters
    ----------
    polygon : (k, 2) float, positively oriented (:func:`polygon_area` > 0), not closed.
    min_angle : float, degrees.

    Returns
    -------
    (k', 2) float polygon, k' <= k.
    """
    P = np.asarray(polygon, dtype=float)
    if min_angle <= 0:
        return P
    for _ in range(len(P)):
        if len(P) <= 3:
            break
        sharp = _interior_angles(P) < min_angle  # < 180 convex, > 180 reflex
        if not sharp.any():
            break
        sharp &= ~np.roll(sharp, 1)  # never two neighbours at once
        if not sharp.any():  # every vertex sharp (impossible for a simple polygon)
            break
        P = P[~sharp]
    return P


def chamfer_corners(polygon, max_angle=60.0, fraction=0.3):
    """Replace every corner with interior angle below ``max_angle`` degrees by a short chamfer.

    Corner ``p`` between edges to ``a`` (before) and ``b`` (after) becomes the two points
    ``p + δ (a - p)/|a - p|`` and ``p + δ (b - p)/|b - p|`` with ``δ = fraction · min(|a - p|,
    |b - p|)``; a corner of angle θ turns into two corners of ``90° + θ/2`` and loses the area
    ``δ² sin θ / 2``. Why: Ruppert/Shewchuk refinement only guarantees its angle bound for
    inputs whose segments meet at angles >= 60° (Shewchuk 2002, "Delaunay refinement
    algorithms for triangular mesh generation", Sec. 4); near a 21–30° corner Triangle's
    ``q20`` output measurably keeps 15–19° triangles.

    Parameters
    ----------
    polygon : (k, 2) float, positively oriented, not closed.
    max_angle : float, degrees (<= 90 so chamfers never create sharper corners).
    fraction : float in (0, 0.5), chamfer length relative to the shorter adjacent edge.

    Returns
    -------
    (k + c, 2) float polygon, ``c`` the number of chamfered corners.
    """
    P = np.asarray(polygon, dtype=float)
    if max_angle <= 0 or len(P) < 3:
        return P
    if not 0 < fraction < 0.5:
        raise ValueError(f"fraction must lie in (0, 0.5), got {fraction}")
    sharp = _interior_angles(P) < min(max_angle, 90.0)
    if not sharp.any():
        return P
    a, b = np.roll(P, 1, axis=0) - P, np.roll(P, -1, axis=0) - P  # (k, 2) to neighbours
    la, lb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    delta = fraction * np.minimum(la, lb)
    first = P + (delta / la)[:, None] * a
    second = P + (delta / lb)[:, None] * b
    reps = np.where(sharp, 2, 1)
    out = np.repeat(P, reps, axis=0)  # (k + c, 2)
    start = np.cumsum(reps) - reps  # index of each vertex's first output slot
    s = start[sharp]
    out[s], out[s + 1] = first[sharp], second[sharp]
    return out


def _contour_loops(comp):
    """Marching-squares outlines of one component: ``(outer, holes)``, closed (k, 2) (x, y).

    ``outer`` runs the positive way round, each hole the negative way (the component on the
    left of every loop, as seen by :func:`remove_sharp_corners` and :func:`chamfer_corners`).
    """
    from skimage.measure import find_contours

    # 1-px zero padding closes every contour; background 8-connected ("low" fully connected)
    contours = [c[:, ::-1] - 1.0 for c in find_contours(np.pad(comp, 1).astype(np.float64), 0.5)]
    areas = [polygon_area(c[:-1]) for c in contours]
    k = int(np.argmax(np.abs(areas)))  # the outer outline encloses every hole's outline
    loops = [c if (a > 0) == (i == k) else c[::-1] for i, (c, a) in enumerate(zip(contours, areas))]
    return loops[k], loops[:k] + loops[k + 1:]


def _simplify_loop(xy, epsilon, min_corner_angle, chamfer_angle, sign):
    """Douglas–Peucker, sharp corners cut, chamfers; ``epsilon`` halved until the loop is simple
    with the orientation ``sign`` (+1 outer, −1 hole); at 0 the raw contour."""
    from skimage.measure import approximate_polygon

    eps = float(epsilon)
    while True:
        P = approximate_polygon(xy, tolerance=eps) if eps > 0 else xy
        P = P[:-1] if np.allclose(P[0], P[-1]) else P  # drop the repeated closing vertex
        keep = np.any(np.abs(P - np.roll(P, 1, axis=0)) > 1e-12, axis=1)  # no duplicates
        P = chamfer_corners(remove_sharp_corners(P[keep], min_corner_angle), chamfer_angle)
        if (len(P) >= 3 and sign * polygon_area(P) > 0 and polygon_is_simple(P)) or eps == 0:
            return np.ascontiguousarray(P, dtype=np.float64)
        eps = eps / 2 if eps > 0.1 else 0.0


def boundary_loops(mask, epsilon=2.0, min_corner_angle=0.0, chamfer_angle=0.0,
                   min_hole_area=None):
    """Outer boundary and hole boundaries of the largest mask component, simplified.

    The outlines are the 0.5 level set of the component (marching squares,
    ``skimage.measure.find_contours`` on a 1-px zero-padded mask: along the pixel edges, half
    a pixel outside the centres of boundary pixels; background pixels 8-connected, so a gap
    that touches the outside at a corner is not a hole), each simplified with
    Douglas–Peucker [DP] (``skimage.measure.approximate_polygon``) to within ``epsilon`` px.
    Holes with fewer than ``min_hole_area`` pixels are filled first (:func:`fill_small_holes`).
    If simplification would make a loop self-intersecting or degenerate, its ``epsilon`` is
    halved until it does not; if two loops then touch or cross (a wall thinner than
    ``epsilon``), every ``epsilon`` is halved (down to 0: the raw marching-squares contours,
    which never meet).

    Parameters
    ----------
    mask : (H, W) mask (anything :func:`mask_from_array` accepts).
    epsilon : float >= 0, Douglas–Peucker tolerance (px).
    min_corner_angle : float, degrees; corners of the component sharper than this are cut
        off (:func:`remove_sharp_corners`); :func:`mesh_from_mask` passes its ``min_angle``.
    chamfer_angle : float, degrees; remaining corners sharper than this are chamfered
        (:func:`chamfer_corners`); :func:`mesh_from_mask` passes 60.
    min_hole_area : None (:data:`MIN_HOLE_AREA` = 16 px) or float px >= 0; ``np.inf``
        ignores every hole.

    Returns
    -------
    outer : (k, 2) float64 polygon ``(x, y)`` in pixel coordinates (pixel ``[i, j]`` centred
        at ``(j, i)``), positively oriented (:func:`polygon_area` > 0), without a repeated
        closing vertex.
    holes : list of (k_i, 2) float64 polygons inside ``outer``, negatively oriented (the
        component on the left of every loop), in no particular order.
    """
    if not epsilon >= 0:
        raise ValueError(f"epsilon must be >= 0 px, got {epsilon}")
    comp = fill_small_holes(_largest_component(mask_from_array(mask)), min_hole_area)
    outer, holes = _contour_loops(comp)
    eps = float(epsilon)
    while True:
        P = _simplify_loop(outer, eps, min_corner_angle, chamfer_angle, +1)
        Hs = [_simplify_loop(h, eps, min_corner_angle, chamfer_angle, -1) for h in holes]
        if not Hs or eps == 0 or loops_are_disjoint([P] + Hs):
            return P, Hs
        eps = eps / 2 if eps > 0.1 else 0.0


def boundary_polygon(mask, epsilon=2.0, min_corner_angle=0.0, chamfer_angle=0.0):
    """Outer boundary of the largest mask component as a simplified polygon (holes ignored).

    ``boundary_loops(mask, ..., min_hole_area=np.inf)[0]``: see :func:`boundary_loops` for
    the outline, the parameters and the result.

    Returns
    -------
    (k, 2) float64 polygon ``(x, y)`` in pixel coordinates, positively oriented, without a
    repeated closing vertex.
    """
    return boundary_loops(mask, epsilon, min_corner_angle, chamfer_angle, np.inf)[0]


# ---------------------------------------------------------------------------------- Triangle
def default_max_area(polygon_or_area, target=TARGET_TRIANGLES):
    """Default Triangle area bound: ``max_area = |area| / (target / 2)``.

    With the ``q`` angle bound, Triangle's triangles end up, on average, about half the area
    bound, so a compact polygon gets about ``target`` (≈ 300) triangles whatever its size in
    pixels. Outlines with many short edges (real drawings) get more, because the triangles
    along the boundary cannot be much larger than the boundary segments.
    """
    a = polygon_or_area
    area = abs(polygon_area(a)) if np.ndim(a) == 2 else abs(float(a))
    if area <= 0:
        raise ValueError("polygon has zero area")
    return area / (target / 2)


def _check_polygon(polygon, name="polygon"):
    P = np.asarray(polygon, dtype=float)
    if P.ndim != 2 or P.shape[1] != 2 or len(P) < 3:
        raise ValueError(f"{name} must have shape (k, 2) with k >= 3 vertices, got {P.shape}")
    if not np.all(np.isfinite(P)):
        raise ValueError(f"{name} contains NaN or inf")
    if len(P) > 3 and np.allclose(P[0], P[-1]):
        P = P[:-1]  # tolerate a repeated closing vertex
    if abs(polygon_area(P)) <= 1e-12 * np.ptp(P, axis=0).max() ** 2:
        raise ValueError(f"{name} has zero area (collinear or repeated vertices)")
    return P


def _point_inside_polygon(P):
    """A point strictly inside a simple polygon: centroid of the largest triangle of its CDT."""
    import triangle as tr

    k = len(P)
    seg = np.stack([np.arange(k), (np.arange(k) + 1) % k], axis=1)
    t = tr.triangulate({"vertices": P, "segments": seg}, "pQ")
    V, T = t["vertices"], t["triangles"]
    a = np.abs(triangle_areas(V, T))
    return V[T[np.argmax(a)]].mean(axis=0)


def triangulate_polygon(polygon, max_area=None, min_angle=20.0, holes=None, points=None):
    """Quality triangle mesh of a polygon (with optional holes and interior vertices) [Tri].

    Calls Triangle with switches ``p q{min_angle} a{max_area} Q``: a *conforming constrained
    Delaunay triangulation* of the planar straight-line graph made of the closed outline
    (and hole outlines) — the outline's segments are edges of the mesh (split by Steiner
    points where needed), triangles outside the outline and inside holes are removed —
    refined by Ruppert/Shewchuk Delaunay refinement until no angle is below ``min_angle``
    degrees and no triangle is larger than ``max_area``. The bound holds away from small
    *input* angles: corners sharper than ``min_angle`` cannot be improved, and corners below
    60° can leave slightly worse triangles nearby (:func:`remove_sharp_corners` and
    :func:`chamfer_corners` fix the outline first; :func:`mesh_from_mask` does so).

    Parameters
    ----------
    polygon : (k, 2) float, simple closed outline ``(x, y)`` (either orientation; a repeated
        closing vertex is tolerated).
    max_area : float > 0 (units²) or None for :func:`default_max_area` (area / 150, giving
        a few hundred triangles).
    min_angle : float in [0, 34] degrees (Triangle is guaranteed to terminate up to 20.7°
        and usually succeeds up to ~33°).
    holes : list of (h_i, 2) float polygons inside ``polygon``, or None.
    points : (m, 2) float extra vertices strictly inside the meshed region (e.g. skeleton
        joints), or None.

    Returns
    -------
    TriMesh, positively oriented. Vertex order: the ``k`` outline vertices (as given, minus a
    closing duplicate), then each hole's vertices, then ``points`` (duplicates merged), then
    Steiner points. ``vertex_indices(mesh, points)`` gives the vertex of each point.
    """
    import triangle as tr

    P = _check_polygon(polygon)
    holes = [] if holes is None else [_check_polygon(h, f"holes[{i}]") for i, h in enumerate(holes)]
    if not 0 <= min_angle <= 34:
        raise ValueError(f"min_angle must lie in [0, 34] degrees (Triangle may not terminate above), "
                         f"got {min_angle}")
    if max_area is None:
        max_area = default_max_area(abs(polygon_area(P)) - sum(abs(polygon_area(h)) for h in holes))
    if not (np.isfinite(max_area) and max_area > 0):
        raise ValueError(f"max_area must be a finite number > 0 (units²), got {max_area}")
    region = abs(polygon_area(P)) - sum(abs(polygon_area(h)) for h in holes)
    if region / max_area > MAX_TRIANGLES:
        raise ValueError(f"max_area {max_area:g} would make about {2 * region / max_area:,.0f} "
                         f"triangles for an area of {region:g} units², more than the limit of "
                         f"{MAX_TRIANGLES:,}; choose max_area >= {region / MAX_TRIANGLES:.3g}")

    loops = [P] + holes
    sizes = [len(L) for L in loops]
    starts = np.cumsum([0] + sizes[:-1])
    segments = np.concatenate([s + np.stack([np.arange(m), (np.arange(m) + 1) % m], axis=1)
                               for s, m in zip(starts, sizes)])
    V = np.concatenate(loops)
    if points is not None:
        Q = np.asarray(points, dtype=float).reshape(-1, 2)
        if not np.all(np.isfinite(Q)):
            raise ValueError("points contain NaN or inf")
        if len(Q):
            from matplotlib.path import Path

            inside = Path(P).contains_points(Q)
            for h in holes:
                inside &= ~Path(h).contains_points(Q)
            if not inside.all():
                j = int(np.flatnonzero(~inside)[0])
                raise ValueError(f"{np.sum(~inside)} of the points lie outside the region to mesh, "
                                 f"the first is points[{j}] = {Q[j].tolist()}; move them inside the "
                                 f"outline or drop them")
            # merge duplicates (e.g. AnimatedDrawings' root and hip joints coincide), keep order
            _, first = np.unique(Q, axis=0, return_index=True)
            Q = Q[np.sort(first)]
            d, _ = cKDTree(V).query(Q)
            V = np.concatenate([V, Q[d > 0]])
    data = {"vertices": V, "segments": segments}
    if holes:
        data["holes"] = np.array([_point_inside_polygon(h) for h in holes])
    area_str = np.format_float_positional(float(max_area), trim="-")
    angle_str = np.format_float_positional(float(min_angle), trim="-")
    out = tr.triangulate(data, f"pq{angle_str}a{area_str}Q")
    X = np.asarray(out["vertices"], dtype=np.float64)
    tris = np.asarray(out["triangles"], dtype=np.int64)
    if len(tris) == 0:
        raise ValueError("Triangle produced no triangles; is the polygon simple and non-degenerate?")
    X, tris = _compact(X, tris)
    return TriMesh(X, _orient_positive(X, tris))


def polygon_mesh(vertices, max_area=None, min_angle=20.0):
    """Quality mesh of a simple polygon: :func:`triangulate_polygon` without holes or points."""
    return triangulate_polygon(vertices, max_area=max_area, min_angle=min_angle)


def mesh_from_mask(mask, max_area=None, epsilon=2.0, min_angle=20.0, points=None,
                   min_hole_area=None):
    """Triangle mesh of the largest component of a mask, with its holes, in pixel coordinates.

    :func:`boundary_loops` (Douglas–Peucker tolerance ``epsilon`` px; corners sharper than
    ``min_angle`` cut off and corners below 60° chamfered, so that Triangle's angle bound
    holds everywhere) followed by :func:`triangulate_polygon` with the hole outlines as holes
    [Tri]: a gap enclosed by the component (the white between an arm and the torso) is not
    meshed over, unless it has fewer than ``min_hole_area`` pixels (then it is filled, like a
    speckle). Douglas–Peucker chords cut up to ``epsilon`` px off convex parts (a 20-px disk
    loses ~7 % of its area at ε = 2). When the meshed area (outline minus holes) differs from
    the mask's (small holes filled) by more than ``AREA_TOLERANCE`` (10 %) — a thin stroke
    collapsed, the gap of a U bridged — ``epsilon`` is halved until it does not (down to 0,
    the marching-squares outlines themselves).

    Parameters
    ----------
    mask : (H, W) mask (anything :func:`mask_from_array` accepts).
    max_area : float px² or None: :func:`default_max_area` of the meshed area (a few
        hundred triangles), but at least ``MIN_PIXEL_AREA`` = 12 px² (about a 5-px
        triangle), so bodies smaller than ~1800 px² get fewer, image-sized triangles.
    epsilon, min_angle : see :func:`boundary_loops`, :func:`triangulate_polygon`.
    points : (m, 2) extra interior vertices in pixels (e.g. skeleton joints), or None;
        find them afterwards with :func:`vertex_indices`. A point inside a hole is an error.
    min_hole_area : None (:data:`MIN_HOLE_AREA` = 16 px) or float px >= 0, smallest hole
        (pixel count) meshed as a hole; ``np.inf`` fills every hole (the outer outline only).

    Returns
    -------
    TriMesh with ``X`` in pixels ``(x, y)``, y down; positively oriented. Its boundary
    (:meth:`TriMesh.boundary_edges`) has one loop per kept hole besides the outer one.
    """
    if not (np.isfinite(epsilon) and epsilon >= 0):
        raise ValueError(f"epsilon must be a finite number >= 0 px, got {epsilon}")
    comp = fill_small_holes(_largest_component(mask_from_array(mask)), min_hole_area)
    target, eps = float(comp.sum()), float(epsilon)
    while True:  # simplify no more than keeps the area of the mask (thin parts, narrow gaps)
        outer, holes = boundary_loops(comp, epsilon=eps, min_corner_angle=min_angle,
                                      chamfer_angle=CHAMFER_ANGLE if min_angle > 0 else 0.0,
                                      min_hole_area=0)
        area = polygon_area(outer) + sum(polygon_area(h) for h in holes)  # holes: < 0
        if abs(area - target) <= AREA_TOLERANCE * target or eps == 0:
            break
        eps = eps / 2 if eps > 0.1 else 0.0
    if max_area is None:  # pixel meshes: no need for triangles below MIN_PIXEL_AREA px²
        max_area = max(default_max_area(area), MIN_PIXEL_AREA)
    return triangulate_polygon(outer, max_area=max_area, min_angle=min_angle, holes=holes,
                               points=points)


def meshes_from_image(image, max_area=None, epsilon=2.0, min_angle=20.0, min_area=64):
    """One mesh per foreground body of an image, largest first.

    :func:`foreground_mask` (alpha or Otsu), :func:`mask_components` (``min_area`` px), then
    :func:`mesh_from_mask` on each component; ``max_area`` None picks the default per body.

    Returns
    -------
    list of TriMesh in pixel coordinates; ValueError "no foreground found" if there is none.
    """
    mask = foreground_mask(image, min_area=min_area)
    comps = mask_components(mask, min_area=min_area)
    if not comps:
        raise ValueError(f"no foreground found in the image (no body of >= {min_area} px "
                         f"darker than a light background or inside the alpha channel); is it "
                         f"blank, uniform or a light drawing on a dark background (then pass "
                         f"1 - image)?")
    return [mesh_from_mask(c, max_area=max_area, epsilon=epsilon, min_angle=min_angle)
            for c in comps]


# ---------------------------------------------------------------------------------- builders
def grid_mesh(nx, ny, width, height, origin=(0.0, 0.0)):
    """Regular grid of ``nx × ny`` rectangular cells, each split into two triangles.

    The diagonals alternate in a checkerboard pattern (no preferred direction, so the mesh
    bends symmetrically). Vertex ``(i, j)`` (column ``i`` in 0..nx, row ``j`` in 0..ny) has
    index ``j (nx + 1) + i`` and position ``origin + (i width / nx, j height / ny)``.

    Returns
    -------
    TriMesh with ``(nx+1)(ny+1)`` vertices and ``2 nx ny`` positively oriented triangles of
    total area ``width · height``; the boundary has ``2 (nx + ny)`` edges.
    """
    nx, ny = int(nx), int(ny)
    if nx < 1 or ny < 1:
        raise ValueError(f"nx and ny must be >= 1 cells, got nx={nx}, ny={ny}")
    if not (width > 0 and height > 0):
        raise ValueError(f"width and height must be > 0, got {width} x {height}")
    ox, oy = (float(o) for o in origin)
    xs = ox + np.linspace(0.0, width, nx + 1)
    ys = oy + np.linspace(0.0, height, ny + 1)
    X = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)  # (ny+1)(nx+1), row-major
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))  # cell column, row: (ny, nx)
    v00 = (j * (nx + 1) + i).ravel()
    v10, v01, v11 = v00 + 1, v00 + nx + 1, v00 + nx + 2
    flip = ((i + j) % 2 == 1).ravel()
    # diagonal v00-v11 (even cells) or v10-v01 (odd cells); all positively oriented (Eq. (A))
    t1 = np.where(flip[:, None], np.stack([v00, v10, v01], 1), np.stack([v00, v10, v11], 1))
    t2 = np.where(flip[:, None], np.stack([v10, v11, v01], 1), np.stack([v00, v11, v01], 1))
    tris = np.stack([t1, t2], axis=1).reshape(-1, 3)
    return TriMesh(X, tris)


def disk_mesh(center, radius, max_area=None, n_boundary=48, min_angle=20.0):
    """Quality mesh of a disk (its inscribed regular ``n_boundary``-gon).

    The mesh area is that of the polygon, ``n r² sin(2π/n) / 2`` (0.3 % below ``π r²`` for
    n = 48). ``max_area`` None: :func:`default_max_area` (a few hundred triangles).
    """
    if not radius > 0:
        raise ValueError(f"radius must be > 0, got {radius}")
    if int(n_boundary) < 3:
        raise ValueError(f"n_boundary must be >= 3, got {n_boundary}")
    th = 2 * np.pi * np.arange(int(n_boundary)) / int(n_boundary)
    poly = np.asarray(center, dtype=float) + radius * np.stack([np.cos(th), np.sin(th)], axis=1)
    return triangulate_polygon(poly, max_area=max_area, min_angle=min_angle)


def strip_mesh(n_tris_target, aspect=10.0, cell=1.0):
    """A long rectangular strip of about ``n_tris_target`` triangles (benchmark mesh).

    A :func:`grid_mesh` of square cells of side ``cell`` with ``ny = round(sqrt(n / (2
    aspect)))`` rows and ``nx = round(n / (2 ny))`` columns, so ``2 nx ny ≈ n`` and the strip
    is ``nx cell`` long (x) by ``ny cell`` wide (y), ``nx / ny ≈ aspect``. Builds 200k
    triangles in a few milliseconds.
    """
    n = int(n_tris_target)
    if n < 2:
        raise ValueError(f"n_tris_target must be >= 2, got {n_tris_target}")
    if not (aspect > 0 and cell > 0):
        raise ValueError(f"aspect and cell must be > 0, got aspect={aspect}, cell={cell}")
    ny = max(1, int(round(np.sqrt(n / (2 * aspect)))))
    nx = max(1, int(round(n / (2 * ny))))
    return grid_mesh(nx, ny, nx * cell, ny * cell)


# ---------------------------------------------------------------------------------- point location
def _barycentric(X, tris, points, tri_index):
    """Barycentric coordinates (m, 3) of ``points`` in triangles ``tri_index`` (>= 0)."""
    P = X[tris[tri_index]]  # (m, 3, 2)
    e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    r = points - P[:, 0]
    det = e1[:, 0] * e2[:, 1] - e2[:, 0] * e1[:, 1]  # 2 × Eq. (A)
    l1 = (r[:, 0] * e2[:, 1] - e2[:, 0] * r[:, 1]) / det
    l2 = (e1[:, 0] * r[:, 1] - r[:, 0] * e1[:, 1]) / det
    return np.stack([1.0 - l1 - l2, l1, l2], axis=1)


def locate_points(mesh, points):
    """Containing triangle and barycentric coordinates of each point.

    Uses matplotlib's trapezoid-map point location (``TrapezoidMapTriFinder``, O(log T) per
    point after an O(T log T) build cached on the mesh).

    Parameters
    ----------
    mesh : TriMesh (rest positions ``mesh.X``).
    points : (m, 2) float, same units as ``mesh.X``.

    Returns
    -------
    tri : (m,) int64, index into ``mesh.tris`` of the containing triangle, -1 outside.
    bary : (m, 3) float64, ``λ`` with ``Σ λ = 1`` and ``points = Σ_k λ_k X[tris[tri, k]]``;
        zeros for points outside.
    """
    pts = np.asarray(points, dtype=float)
    single = pts.ndim == 1
    pts = pts.reshape(-1, 2)
    if not np.all(np.isfinite(pts)):
        raise ValueError("points contain NaN or inf")
    tri = np.asarray(mesh._trifinder(pts[:, 0], pts[:, 1]), dtype=np.int64)
    bary = np.zeros((len(pts), 3))
    found = tri >= 0
    bary[found] = _barycentric(mesh.X, mesh.tris, pts[found], tri[found])
    if single:
        return tri[0], bary[0]
    return tri, bary


def point_in_mesh(mesh, points):
    """(m,) bool: whether each point of ``points`` (m, 2) lies in a triangle of ``mesh``."""
    return np.atleast_1d(locate_points(mesh, points)[0]) >= 0


def vertex_indices(mesh, points, tol=1e-9):
    """Index of the mesh vertex at each point (e.g. skeleton joints inserted as ``points``).

    Parameters
    ----------
    mesh : TriMesh.
    points : (m, 2) float, same units as ``mesh.X``.
    tol : float, largest accepted distance (units).

    Returns
    -------
    (m,) int64 vertex indices, -1 where no vertex lies within ``tol``.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    d, idx = cKDTree(mesh.X).query(pts)
    return np.where(d <= tol, idx, -1).astype(np.int64)
