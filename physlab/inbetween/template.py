"""Deformation templates of keyframe drawings (Brodt & Bessmeltsev 2024, Secs. 4.1–4.2, 5.1).

A :class:`Template` is the triangle mesh of one keyframe's foreground, in the keyframe's
pixel coordinates, with the skeleton's *handles* (every joint and every bone midpoint) tied
to it, and the keyframe image as its texture: the mesh's rest positions ``X`` are the
texture coordinates (Sec. 5.1, "we use the (x, y) coordinates of the mesh as the (u, v)
texture coordinates").

Building one (:func:`build_template`):

1. **Foreground mask** (Sec. 4.1). The paper predicts it with a U-Net on DINOv2 features,
   whose trained weights physlab does not have. The honest CPU substitute is
   :func:`classical_foreground_mask` (the alpha channel, or Otsu's threshold for ink on a
   light background, closed, hole-filled: :func:`physlab.mesh.foreground_mask`). Any callable
   ``image -> (H, W) bool`` can be passed as ``mask_predictor`` — that is where a learned
   segmenter plugs in — or the mask itself as ``mask``.
2. **Template initialisation** (Sec. 4.2): the mask's outline simplified by Douglas–Peucker
   (ε = 2 px), a conforming Delaunay triangulation with Triangle (minimum angle 20°), and
   the handles inserted as mesh vertices ("point constraints"). The mask is first dilated by
   ``grow`` px so that the mesh also covers the antialiased ink outline (Douglas–Peucker
   chords cut up to ε px off convex parts). A handle that falls outside the mesh (a hand
   joint drawn at the tip of a finger, say) is tied to its nearest triangle by extrapolated
   barycentric coordinates instead of being a vertex.

Occlusion layers (Secs. 4.3–4.4) are the subject of a follow-up: ``Template.layers`` is where
they will live; templates built here have none.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import sparse

from ..mesh import TriMesh, foreground_mask, locate_points, mask_from_array, mesh_from_mask
from .skeleton import Skeleton

__all__ = ["Template", "build_template", "classical_foreground_mask", "as_rgba_float"]


def as_rgba_float(image, name="image"):
    """``image`` as (H, W, 4) float32 straight RGBA in [0, 1] (RGB becomes opaque).

    Accepts (H, W), (H, W, 3), (H, W, 4) uint8, uint16 or float in [0, 1]
    (:func:`physlab.image.as_float`); raises ValueError otherwise (wrong shape, NaN, values
    outside [0, 1], smaller than 2×2).
    """
    from physlab.image import as_float

    return as_float(image, name, channels=4, min_size=2)


def classical_foreground_mask(image):
    """Foreground mask without a network: alpha channel, or Otsu on a light background.

    physlab's stand-in for the paper's DINOv2 U-Net (Sec. 4.1); see
    :func:`physlab.mesh.foreground_mask`. Returns (H, W) bool.
    """
    return foreground_mask(image)


@dataclass(frozen=True, eq=False)
class Template:
    """A keyframe's deformable template.

    Attributes
    ----------
    mesh : TriMesh, rest positions ``X`` (n, 2) in the keyframe's pixels (= texture coords).
    skeleton : Skeleton of the keyframe (pixels).
    image : (H, W, 4) float32 straight RGBA texture in [0, 1].
    mask : (H, W) bool foreground mask the mesh was built from.
    handle_tris : (K,) int64 triangle of each handle, K = J + B (joints then bone midpoints,
        :meth:`Skeleton.handles` order).
    handle_bary : (K, 3) barycentric coordinates of each handle in its triangle (may be
        outside [0, 1] for handles outside the mesh).
    handle_vertices : (K,) int64 mesh vertex at each handle, -1 when the handle is not a
        vertex.
    layers : tuple, occlusion layers (empty: single-layer template; follow-up issue).
    """

    mesh: TriMesh
    skeleton: Skeleton
    image: np.ndarray
    mask: np.ndarray
    handle_tris: np.ndarray
    handle_bary: np.ndarray
    handle_vertices: np.ndarray
    layers: tuple = field(default=())

    def __repr__(self):
        h, w = self.image.shape[:2]
        inside = int(np.sum(self.handle_vertices >= 0))
        return (f"Template({self.mesh.n} vertices, {self.mesh.n_tris} triangles, "
                f"{len(self.handle_tris)} handles ({inside} vertices), image {h}x{w})")

    @property
    def X(self):
        """(n, 2) rest vertex positions in pixels."""
        return self.mesh.X

    @property
    def tris(self):
        """(T, 3) int triangles."""
        return self.mesh.tris

    @property
    def shape(self):
        """(H, W) of the keyframe image."""
        return self.image.shape[:2]

    def handle_matrix(self):
        """Sparse (K, n) matrix ``B`` with ``B @ x`` = the handle positions of vertices ``x``."""
        K, n = len(self.handle_tris), self.mesh.n
        rows = np.repeat(np.arange(K), 3)
        cols = self.mesh.tris[self.handle_tris].ravel()
        return sparse.csr_matrix((self.handle_bary.ravel(), (rows, cols)), shape=(K, n))

    def handle_positions(self, x):
        """(K, 2) handle positions of the deformed vertices ``x`` (n, 2)."""
        x = np.asarray(x, dtype=float)
        return np.einsum("kc,kcd->kd", self.handle_bary, x[self.mesh.tris[self.handle_tris]])

    def targets(self, skeleton):
        """(K, 2) handle targets of a posed skeleton with this template's topology."""
        from .skeleton import check_compatible

        check_compatible(self.skeleton, skeleton, ("template skeleton", "target skeleton"))
        return skeleton.handles()

    def render(self, x, out_shape=None, supersample=2):
        """The keyframe texture warped by deformed vertices ``x`` (n, 2).

        Returns (H, W, 4) float32 straight RGBA (:func:`physlab.render.warp_texture`);
        ``out_shape`` defaults to the keyframe's size.
        """
        from ..render import warp_texture

        return warp_texture(self.image, self.mesh.X, x, self.mesh.tris,
                            self.shape if out_shape is None else out_shape,
                            supersample=supersample)

    def render_inpainted(self, x, out_shape=None, supersample=2):
        """The visible pixels whose texture came from inpainting (Brodt & Bessmeltsev 2024,
        Sec. 5.2's q): none — a single sheet is textured by its keyframe alone. Layered
        templates override this (:meth:`~physlab.inbetween.occlusion.LayeredTemplate.
        render_inpainted`).

        Parameters
        ----------
        x : (n, 2) deformed vertex positions; out_shape : (H, W), default the keyframe's;
        supersample : unused (the signature of :meth:`render`).

        Returns
        -------
        (H, W) bool, all False.
        """
        x = np.asarray(x, dtype=float)
        if x.shape != self.X.shape:
            raise ValueError(f"x must have shape {self.X.shape} (one position per template "
                             f"vertex), got {x.shape}")
        H, W = self.shape if out_shape is None else (int(out_shape[0]), int(out_shape[1]))
        return np.zeros((H, W), bool)


def _check_joints_in_image(skeleton, shape, name):
    H, W = shape
    xy = skeleton.xy
    bad = np.flatnonzero((xy[:, 0] < -0.5) | (xy[:, 0] > W - 0.5)
                         | (xy[:, 1] < -0.5) | (xy[:, 1] > H - 0.5))
    if bad.size:
        j = bad[0]
        raise ValueError(f"{name}: joint {skeleton.names[j]!r} at ({xy[j, 0]:.1f}, "
                         f"{xy[j, 1]:.1f}) lies outside the {W}x{H} image "
                         f"({bad.size} joint(s) outside); skeletons are in pixel coordinates")


def _unique_points(P, tol):
    """Indices of a subset of ``P`` with pairwise distances > tol (first occurrence kept)."""
    from scipy.spatial import cKDTree

    keep = np.ones(len(P), bool)
    for i, j in sorted(cKDTree(P).query_pairs(tol)):
        if keep[i] and keep[j]:
            keep[j] = False
    return np.flatnonzero(keep)


def keyframe_mask(image, skeleton, mask=None, mask_predictor=None, grow=3, name="keyframe"):
    """Checked inputs of a template: ``(rgba image, mask, mask grown by grow px)``.

    The image as (H, W, 4) float RGBA, the skeleton's joints inside it, the foreground mask
    given or predicted (``mask_predictor``, default :func:`classical_foreground_mask`), of the
    image's size and not empty. Raises ValueError / TypeError naming ``name``'s problem.
    """
    from scipy import ndimage

    img = as_rgba_float(image, name)
    if not isinstance(skeleton, Skeleton):
        raise TypeError(f"skeleton must be a physlab.inbetween.Skeleton, got "
                        f"{type(skeleton).__name__}")
    H, W = img.shape[:2]
    _check_joints_in_image(skeleton, (H, W), name)
    if mask is None:
        mask = (mask_predictor or classical_foreground_mask)(img)
    mask = mask_from_array(mask)
    if mask.shape != (H, W):
        raise ValueError(f"{name}: mask shape {mask.shape} differs from the image's {(H, W)}")
    if not mask.any():
        raise ValueError(f"{name}: the foreground mask is empty — nothing to mesh (is the "
                         "drawing on a light background, or does its alpha channel mark it?)")
    if grow < 0:
        raise ValueError(f"grow must be >= 0 px, got {grow}")
    grown = ndimage.binary_dilation(mask, iterations=int(grow)) if grow else mask
    return img, mask, grown


def build_template(image, skeleton, mask=None, mask_predictor=None, max_area=None,
                   epsilon=2.0, min_angle=20.0, grow=3, name="keyframe"):
    """Template of a keyframe drawing: mask → outline → Triangle mesh with handle vertices.

    Brodt & Bessmeltsev 2024, Secs. 4.1–4.2 (single layer, no occlusions).

    Parameters
    ----------
    image : (H, W, 3|4) uint8 or float in [0, 1], the keyframe.
    skeleton : Skeleton in the keyframe's pixel coordinates.
    mask : (H, W) foreground mask, or None to predict one.
    mask_predictor : callable ``image -> (H, W) bool`` used when ``mask`` is None; default
        :func:`classical_foreground_mask` (the seam for a learned segmenter).
    max_area : float px² or None (:func:`physlab.mesh.mesh_from_mask` default: a few
        hundred triangles, like the paper's Table 2 meshes).
    epsilon : float px, Douglas–Peucker tolerance (paper: 2 px).
    min_angle : float degrees, Triangle's minimum angle (paper: 20°).
    grow : int px ≥ 0, dilation of the mask before meshing so the ink outline is covered.
    name : str used in error messages.

    Returns
    -------
    Template.

    Raises
    ------
    ValueError for an empty mask, a mask of another size, joints outside the image.
    """
    from scipy import ndimage

    img, mask, grown = keyframe_mask(image, skeleton, mask, mask_predictor, grow, name)
    H, W = img.shape[:2]
    handles = skeleton.handles()
    # insert distinct handles lying well inside the foreground as vertices
    inside = np.zeros(len(handles), bool)
    ij = np.round(handles[:, ::-1]).astype(int)
    ok = (ij[:, 0] >= 0) & (ij[:, 0] < H) & (ij[:, 1] >= 0) & (ij[:, 1] < W)
    dist_in = ndimage.distance_transform_edt(grown)
    inside[ok] = dist_in[ij[ok, 0], ij[ok, 1]] > epsilon + 1.5
    cand = np.flatnonzero(inside)
    cand = cand[_unique_points(handles[cand], 0.5)] if cand.size else cand
    mesh = mesh_from_mask(grown, max_area=max_area, epsilon=epsilon, min_angle=min_angle,
                          points=handles[cand] if cand.size else None)
    from scipy.spatial import cKDTree

    d, vid = cKDTree(mesh.X).query(handles)
    handle_vertices = np.where(d < 1e-6, vid, -1).astype(np.int64)
    tri, bary = locate_points(mesh, handles)
    tri, bary = np.atleast_1d(tri).astype(np.int64), np.atleast_2d(bary)
    for k in np.flatnonzero(handle_vertices >= 0):  # exact one-hot rows for vertex handles
        t = np.flatnonzero((mesh.tris == handle_vertices[k]).any(axis=1))[0]
        tri[k] = t
        bary[k] = (mesh.tris[t] == handle_vertices[k]).astype(float)
    missing = np.flatnonzero(tri < 0)
    if missing.size:  # outside the mesh: extrapolate from the nearest triangle (centroid)
        from ..mesh import _barycentric

        cent = mesh.X[mesh.tris].mean(axis=1)
        near = cKDTree(cent).query(handles[missing])[1]
        tri[missing] = near
        bary[missing] = _barycentric(mesh.X, mesh.tris, handles[missing], near)
    return Template(mesh=mesh, skeleton=skeleton, image=img, mask=mask,
                    handle_tris=tri, handle_bary=bary, handle_vertices=handle_vertices)
