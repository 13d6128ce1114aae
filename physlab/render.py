"""Textured-mesh rendering: warp a drawing by a deformed triangle mesh; control images; video out.

PhysAnimator (Xie et al. 2025) renders its simulated animations with a sketch-guided video
diffusion model (ToonCrafter + a sketch ControlNet): the simulated mesh is turned into one
sketch/control image per frame, and the model repaints the first frame along them. We do not
have those weights (nor the GPU time), so physlab's honest CPU substitute is the classic one:
**warp the drawing by the simulated mesh** (piecewise-affine texture mapping), and also produce
the per-frame sketch/control images such a model consumes (:func:`edge_map`). A diffusion
renderer would plug in behind the :class:`Renderer` protocol with the same inputs (the
per-frame control images and the first frame).

Conventions (see DESIGN.md)
---------------------------
* Images are ``(H, W, 3|4)`` uint8 or float in ``[0, 1]``.
* Pixel coordinates are ``(x, y)`` = ``(column, row)`` with **y down**, and the *centre* of
  pixel ``(row i, column j)`` is the point ``(x, y) = (j, i)`` (as in scikit-image and
  OpenCV). An image of size ``(H, W)`` therefore covers ``[-0.5, W - 0.5] × [-0.5, H - 0.5]``.
* A mesh is plain arrays: texture (rest) coordinates ``X`` ``(n, 2)`` in the texture's pixel
  frame, deformed positions ``x`` ``(n, 2)`` in the output's pixel frame, triangles ``tris``
  ``(T, 3)`` int. Either orientation may occur (inverted triangles render, mirrored).
* RGBA layers returned by :func:`warp_texture` use **straight** (non-premultiplied) alpha;
  internally everything that filters (bilinear sampling, box downsampling) is done on
  premultiplied colour, so no dark/coloured fringes appear at silhouettes.

The warp (:func:`warp_texture`)
-------------------------------
1. Supersample: output and texture are both taken at ``s×`` resolution. The texture is
   magnified by pixel replication, so a point ``p`` in pixel units maps to ``s (p + 0.5) - 0.5``
   in the fine grid; with this choice an identity mesh reproduces the texture exactly after
   the final box filter (plain bilinear at the fine sample positions would blur it).
2. Rasterise all triangles at once with vectorised scanlines: for every triangle and every
   fine pixel row its horizontal span ``[x_left, x_right)`` is computed from its edges; a fine
   pixel whose centre ``(c, r)`` satisfies ``ceil(y_top) <= r < ceil(y_bottom)`` and
   ``ceil(x_left) <= c < ceil(x_right)`` is covered. Shared edges are evaluated with the same
   floating-point operations (endpoints ordered by y) in both neighbours, so the half-open
   rule covers every pixel of a mesh exactly once (no cracks, no double coverage).
3. For a covered pixel of triangle ``t`` the texture position is the affine map
   ``u = J_t (p - p0) + q0`` with ``J_t = [q1 - q0, q2 - q0] [p1 - p0, p2 - p0]^-1``, i.e.
   barycentric interpolation of ``X`` (this is the inverse of PhysAnimator supp. Eq. (6)'s
   deformation gradient). It is well defined for inverted triangles (det < 0) as well.
4. Sample the premultiplied texture bilinearly there (``cv2.remap`` on float32), then
   box-downsample colour and coverage by ``s``
   (``cv2.resize(..., INTER_AREA)`` is an exact box filter for an integer factor), so edges
   get fractional alpha (antialiasing), and un-premultiply.

Where a mesh overlaps itself, the triangle that comes **later** in ``tris`` wins (it is
written last); the choice is deterministic for a given mesh. Overlapping *bodies* are
ordered by :func:`render_bodies`' ``depth``.
"""
from __future__ import annotations

import base64
import tempfile
from pathlib import Path
from typing import Protocol, Sequence, runtime_checkable

import numpy as np

from physlab._io import atomic_write
from physlab.image import as_float, over_white, to_uint8

__all__ = [
    "warp_texture", "composite", "render_bodies", "edge_map",
    "Renderer", "WarpRenderer",
    "frames_to_gif", "frames_to_mp4", "frames_to_html",
]

_LUMA = np.array([0.2125, 0.7154, 0.0721], np.float32)  # Rec. 709, as skimage.color.rgb2gray


# --------------------------------------------------------------------------- input checks
def _as_float_image(image, name="image"):
    """(H, W) / (H, W, 1|3|4) uint8, uint16 or float in [0, 1] -> float32 (H, W, 4) straight
    RGBA (:func:`physlab.image.as_float`)."""
    return as_float(image, name, channels=4)


def _check_points(P, name, n=None):
    P = np.asarray(P, dtype=float)
    if P.ndim != 2 or P.shape[1] != 2:
        raise ValueError(f"{name} must have shape (n, 2), got {P.shape}")
    if n is not None and len(P) != n:
        raise ValueError(f"{name} has {len(P)} points but X has {n}; they must correspond")
    if not np.isfinite(P).all():
        raise ValueError(f"{name} contains NaN or inf (did the simulation blow up?)")
    return P


def _check_tris(tris, n):
    tris = np.asarray(tris)
    if tris.ndim != 2 or tris.shape[1] != 3 or not np.issubdtype(tris.dtype, np.integer):
        raise ValueError(
            f"tris must be an int array of shape (T, 3), got {tris.dtype} {tris.shape}")
    if tris.size and (tris.min() < 0 or tris.max() >= n):
        raise ValueError(f"tris refers to vertices outside 0..{n - 1}")
    return tris.astype(np.int64, copy=False)


def _check_size(size, name="out_shape"):
    try:
        H, W = int(size[0]), int(size[1])
    except (TypeError, IndexError, ValueError):
        raise ValueError(f"{name} must be (H, W) in pixels, got {size!r}") from None
    if H <= 0 or W <= 0:
        raise ValueError(f"{name} must be positive (H, W), got {(H, W)}")
    return H, W


def _check_supersample(s):
    if int(s) != s or s < 1:
        raise ValueError(f"supersample must be an integer >= 1, got {s!r}")
    return int(s)


# ------------------------------------------------------------------------ the warp itself
def _prepare_texture(texture, s):
    """Premultiplied float32 RGBA texture magnified ×s by pixel replication and padded by one
    replicated fine texel on every side: (s·Ht + 2, s·Wt + 2, 4)."""
    import cv2

    t = _as_float_image(texture, "texture")
    t[..., :3] *= t[..., 3:4]  # premultiply
    if s > 1:  # pixel replication (same as np.repeat along both axes, ~8x faster)
        t = cv2.resize(t, (s * t.shape[1], s * t.shape[0]), interpolation=cv2.INTER_NEAREST_EXACT)
    return cv2.copyMakeBorder(t, 1, 1, 1, 1, cv2.BORDER_REPLICATE)


def _scanline_spans(P, tris, H, W):
    """Vectorised scanline rasterisation of triangles ``P[tris]`` on an (H, W) pixel grid.

    P : (n, 2) float64 vertex positions in pixel units (pixel centres at integers).
    Returns per span (one row of one triangle): ``tid`` (S,) int64, ``row`` (S,) int64,
    ``c0`` (S,) int64 first column, ``length`` (S,) int64 (> 0). Coverage rule: see module
    docstring (half-open, watertight across shared edges).
    """
    T = len(tris)
    if T == 0:
        z = np.zeros(0, np.int64)
        return z, z, z, z
    ys = P[tris, 1]                                              # (T, 3)
    order = np.argsort(ys, axis=1, kind="stable")
    v = np.take_along_axis(tris, order, axis=1)                  # (T, 3) top, mid, bottom
    y_top, y_mid, y_bot = (P[v[:, k], 1] for k in range(3))

    # rows r with ceil(y_top) <= r < ceil(y_bot), clipped to the image (clip before casting)
    r0 = np.ceil(np.clip(y_top, -1.0, H)).astype(np.int64).clip(0, H)
    r1 = np.ceil(np.clip(y_bot, -1.0, H)).astype(np.int64).clip(0, H)
    nrows = np.maximum(r1 - r0, 0)
    tid = np.repeat(np.arange(T), nrows)                         # (S,)
    start = np.cumsum(nrows) - nrows
    row = r0[tid] + (np.arange(len(tid)) - np.repeat(start, nrows))
    rf = row.astype(float)

    def edge_x(a, b):
        """x where the scanline crosses edge (a, b). Endpoints always come ordered top to
        bottom (sorted by y), so both triangles sharing an edge compute bit-identical x."""
        xa, ya = P[a, 0], P[a, 1]
        dy = P[b, 1] - ya
        slope = np.divide(P[b, 0] - xa, dy, out=np.zeros_like(dy), where=dy != 0)
        return xa[tid] + (rf - ya[tid]) * slope[tid]

    x_long = edge_x(v[:, 0], v[:, 2])
    upper = rf < y_mid[tid]
    x_short = np.where(upper, edge_x(v[:, 0], v[:, 1]), edge_x(v[:, 1], v[:, 2]))
    xl = np.minimum(x_long, x_short)
    xr = np.maximum(x_long, x_short)
    c0 = np.ceil(np.clip(xl, -1.0, W)).astype(np.int64).clip(0, W)
    c1 = np.ceil(np.clip(xr, -1.0, W)).astype(np.int64).clip(0, W)
    length = c1 - c0
    keep = length > 0
    return tid[keep], row[keep], c0[keep], length[keep]


def _texture_maps(Q, P, tris, H, W):
    """Fine-grid remap tables: for each covered output pixel, the texture position.

    Q : (n, 2) texture positions (fine texel units), P : (n, 2) output positions (fine pixel
    units). Returns ``map_x, map_y`` (H, W) float32; uncovered pixels hold -1e4 (far outside
    the texture, so they sample transparent black).
    """
    map_x = np.full((H, W), -1e4, np.float32)
    map_y = np.full((H, W), -1e4, np.float32)
    if len(tris) == 0:
        return map_x, map_y
    # per-triangle affine map output -> texture: u = J (p - p0) + q0
    p0, q0 = P[tris[:, 0]], Q[tris[:, 0]]
    Dp = np.stack([P[tris[:, 1]] - p0, P[tris[:, 2]] - p0], axis=2)   # (T, 2, 2) columns
    Dq = np.stack([Q[tris[:, 1]] - q0, Q[tris[:, 2]] - q0], axis=2)
    det = Dp[:, 0, 0] * Dp[:, 1, 1] - Dp[:, 0, 1] * Dp[:, 1, 0]       # signed: any orientation
    ok = np.abs(det) > 1e-12
    inv_det = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
    Dp_inv = np.empty_like(Dp)
    Dp_inv[:, 0, 0], Dp_inv[:, 0, 1] = Dp[:, 1, 1] * inv_det, -Dp[:, 0, 1] * inv_det
    Dp_inv[:, 1, 0], Dp_inv[:, 1, 1] = -Dp[:, 1, 0] * inv_det, Dp[:, 0, 0] * inv_det
    J = Dq @ Dp_inv                                                   # (T, 2, 2)
    c = q0 - np.einsum("tij,tj->ti", J, p0)                           # u = J p + c

    tid, row, col0, length = _scanline_spans(P, tris, H, W)
    if len(tid) == 0:
        return map_x, map_y
    # texture position at each span's first pixel and its step per pixel (column)
    Jt, ct = J[tid], c[tid]
    u0 = (Jt[:, 0, 0] * col0 + Jt[:, 0, 1] * row + ct[:, 0]).astype(np.float32)
    v0 = (Jt[:, 1, 0] * col0 + Jt[:, 1, 1] * row + ct[:, 1]).astype(np.float32)
    du = Jt[:, 0, 0].astype(np.float32)
    dv = Jt[:, 1, 0].astype(np.float32)
    # expand spans to pixels: k = 0..length-1 within each span
    M = int(length.sum())
    first = np.cumsum(length) - length
    k = (np.arange(M, dtype=np.int64) - np.repeat(first, length)).astype(np.float32)
    flat = np.repeat(row * W + col0, length) + k.astype(np.int64)
    # numpy assigns repeated indices in order, so later triangles win on self-overlap
    map_x.ravel()[flat] = np.repeat(u0, length) + k * np.repeat(du, length)
    map_y.ravel()[flat] = np.repeat(v0, length) + k * np.repeat(dv, length)
    return map_x, map_y


def _warp_prepared(tex_fine, X, x, tris, H, W, s):
    """Core of :func:`warp_texture` on an already prepared texture (see ``_prepare_texture``).
    Returns float32 (H, W, 4) straight RGBA."""
    import cv2

    # pixel units -> fine units (+1 for the one-texel border of the prepared texture)
    Q = s * (X + 0.5) - 0.5 + 1.0
    P = s * (x + 0.5) - 0.5
    map_x, map_y = _texture_maps(Q, P, tris, s * H, s * W)
    fine = cv2.remap(tex_fine, map_x, map_y, cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0, 0))
    if fine.ndim == 2:  # cv2 drops a singleton channel axis; never for 4 channels
        fine = fine[..., None]
    out = cv2.resize(fine, (W, H), interpolation=cv2.INTER_AREA) if s > 1 else fine
    alpha = out[..., 3:4]
    out[..., :3] = np.divide(out[..., :3], alpha, out=np.zeros_like(out[..., :3]),
                             where=alpha > 1e-6)                      # un-premultiply
    return np.clip(out, 0.0, 1.0, out=out)


def warp_texture(texture, X, x, tris, out_shape, supersample=2):
    """Piecewise-affine warp of ``texture`` by a deformed triangle mesh.

    Every output pixel covered by a deformed triangle takes the texture colour at the point
    with the same barycentric coordinates in the rest (texture) triangle, sampled bilinearly;
    edges are antialiased by rendering ``supersample``× larger and box-filtering.

    Parameters
    ----------
    texture : (Ht, Wt, 3|4) or (Ht, Wt) uint8, or float in [0, 1]. RGB is opaque.
    X : (n, 2) float, texture coordinates of the vertices, texture pixels (x right, y down).
    x : (n, 2) float, deformed vertex positions, output pixels (x right, y down).
    tris : (T, 3) int, triangles; either orientation, inverted triangles render mirrored.
    out_shape : (H, W) ints (extra trailing entries ignored), the output size in pixels.
    supersample : int >= 1, antialiasing factor per axis.

    Returns
    -------
    (H, W, 4) float32 in [0, 1], **straight** (non-premultiplied) RGBA. Pixels outside the
    deformed mesh are fully transparent (0, 0, 0, 0); silhouette pixels have fractional
    alpha ≈ covered area fraction. Texture positions outside the texture are transparent
    (beyond a one-texel clamp at its border). On self-overlap the later triangle wins.

    Notes
    -----
    Pixel ``(row i, col j)`` has its centre at ``(x, y) = (j, i)``; a mesh covering a whole
    ``Ht × Wt`` texture has corners at ``(-0.5, -0.5)`` and ``(Wt - 0.5, Ht - 0.5)``. The
    identity mesh ``x == X`` reproduces the texture exactly; see the module docstring for
    the algorithm.
    """
    H, W = _check_size(out_shape)
    s = _check_supersample(supersample)
    X = _check_points(X, "X")
    x = _check_points(x, "x", len(X))
    tris = _check_tris(tris, len(X))
    if max(s * H, s * W) + 2 >= 32767:
        raise ValueError(f"supersampled output {s * H}x{s * W} exceeds OpenCV's 32767 limit; "
                         "lower supersample or out_shape")
    tex = _prepare_texture(texture, s)
    if max(tex.shape[:2]) >= 32767:
        raise ValueError(f"supersampled texture {tex.shape[:2]} exceeds OpenCV's 32767 limit")
    return _warp_prepared(tex, X, x, tris, H, W, s)


# ---------------------------------------------------------------------------- compositing
def _background_canvas(background, size):
    """Opaque float32 (H, W, 3) canvas from a flat colour or an RGB(A) image (RGBA is
    flattened over white)."""
    H, W = size
    if background is None:
        background = (1.0, 1.0, 1.0)
    b = np.asarray(background)
    if b.ndim == 1:
        if b.shape[0] not in (3, 4):
            raise ValueError(f"background colour must be (r, g, b) in [0, 1], got {background!r}")
        b = b.astype(np.float64)
        if b.min() < 0 or b.max() > 1:
            raise ValueError(f"background colour must lie in [0, 1], got {background!r} "
                             "(divide 0..255 values by 255)")
        return np.broadcast_to(b[:3].astype(np.float32), (H, W, 3)).copy()
    img = as_float(b, "background", channels=3)
    if img.shape[:2] != (H, W):
        raise ValueError(f"background image is {img.shape[:2]} but the frame is {(H, W)}")
    return over_white(img)


def _finish(rgb, dtype):
    if np.dtype(dtype) == np.uint8:
        return to_uint8(rgb, clip=True)
    if np.issubdtype(np.dtype(dtype), np.floating):
        return np.clip(rgb, 0, 1).astype(dtype, copy=False)
    raise ValueError(f"dtype must be np.uint8 or a float dtype, got {dtype!r}")


def composite(layers, background=None, size=None, dtype=np.float32):
    """Alpha-over compositing of straight-alpha RGBA layers, first layer at the back.

    ``C ← α_i c_i + (1 − α_i) C`` for each layer ``i`` in order (Porter & Duff 1984 "over",
    straight alpha, over an opaque canvas).

    Parameters
    ----------
    layers : sequence of (H, W, 4) (or (H, W, 3) = opaque) float in [0, 1] or uint8 images,
        straight alpha (as returned by :func:`warp_texture`).
    background : None (white), a colour ``(r, g, b)`` floats in [0, 1], or an (H, W, 3|4)
        image (uint8 or float); an RGBA background is first flattened over white.
    size : (H, W), required only when there are no layers and no background image.
    dtype : ``np.float32`` (default, values in [0, 1]), any float dtype, or ``np.uint8``.

    Returns
    -------
    (H, W, 3) RGB image of ``dtype``.
    """
    layers = [_as_float_image(L, f"layers[{i}]") for i, L in enumerate(layers)]
    shapes = {L.shape[:2] for L in layers}
    bg = np.asarray(background) if background is not None else None
    if bg is not None and bg.ndim >= 2:
        shapes.add(bg.shape[:2])
    if size is not None:
        shapes.add(_check_size(size, "size"))
    if not shapes:
        raise ValueError("composite needs `size=(H, W)` when there are no layers and no "
                         "background image")
    if len(shapes) > 1:
        raise ValueError(
            f"layers, background and size disagree on the frame size: {sorted(shapes)}")
    out = _background_canvas(background, shapes.pop())
    for L in layers:
        a = L[..., 3:4]
        out *= 1.0 - a
        out += a * L[..., :3]
    return _finish(out, dtype)


def _over_rgba(layers, size):
    """Straight-alpha RGBA union of layers (first at the back) over a transparent canvas."""
    H, W = size
    acc = np.zeros((H, W, 4), np.float32)  # premultiplied accumulator
    for L in layers:
        a = L[..., 3:4]
        acc *= 1.0 - a
        acc[..., :3] += a * L[..., :3]
        acc[..., 3:4] += a
    A = acc[..., 3:4]
    acc[..., :3] = np.divide(acc[..., :3], A, out=np.zeros_like(acc[..., :3]), where=A > 1e-6)
    return acc


def _back_to_front(depth, n):
    """Drawing order from depths (larger = further back = drawn first); stable on ties."""
    if depth is None:
        return np.arange(n)
    d = np.asarray(depth, dtype=float)
    if d.shape != (n,):
        raise ValueError(f"depth must have one value per body, shape ({n},), got {d.shape}")
    return np.argsort(-d, kind="stable")


def _check_bodies(textures, X_list, tris_list, x_list=None):
    n = len(textures)
    lens = {"textures": n, "X_list": len(X_list), "tris_list": len(tris_list)}
    if x_list is not None:
        lens["x_list"] = len(x_list)
    if len(set(lens.values())) != 1:
        raise ValueError(f"need one entry per body in every list, got lengths {lens}")


def render_bodies(textures, X_list, x_list, tris_list, size, depth=None, background=(1, 1, 1),
                  supersample=2):
    """Render several textured bodies into one RGB frame.

    Parameters
    ----------
    textures : list of B textures (see :func:`warp_texture`).
    X_list, x_list : lists of B (n_b, 2) float arrays, texture and deformed positions (px).
    tris_list : list of B (T_b, 3) int arrays.
    size : (H, W) output size in pixels.
    depth : None (list order: first body at the back) or (B,) floats; larger depth = further
        back (drawn first). Ties keep list order.
    background : colour (r, g, b) in [0, 1] or an (H, W, 3|4) image; see :func:`composite`.
    supersample : antialiasing factor, see :func:`warp_texture`.

    Returns
    -------
    (H, W, 3) uint8 frame.
    """
    _check_bodies(textures, X_list, tris_list, x_list)
    H, W = _check_size(size, "size")
    layers = [warp_texture(textures[b], X_list[b], x_list[b], tris_list[b], (H, W), supersample)
              for b in _back_to_front(depth, len(textures))]
    return composite(layers, background, size=(H, W), dtype=np.uint8)


# ------------------------------------------------------------------------ control images
def edge_map(image, sigma=1.0, method="canny", dilate=0, channels="luminance", low_threshold=0.1,
             high_threshold=0.2, dog_k=1.6, dog_threshold=0.02):
    """Line-art control image: dark lines on white, like a sketch ControlNet's input.

    Edges are found on the luminance of the image flattened over white, plus the edges of its
    alpha channel (so silhouettes show even where a body's colour matches the background).
    Luminance misses boundaries between colours of equal brightness (e.g. red on blue);
    ``channels="rgb"`` adds the edges of each colour channel as well.

    Parameters
    ----------
    image : (H, W), (H, W, 3) or (H, W, 4) uint8 or float in [0, 1].
    sigma : float > 0, Gaussian scale in pixels.
    method : ``"canny"`` — :func:`skimage.feature.canny` (thin, 1-px lines at the gradient
        maxima; thresholds ``low_threshold``/``high_threshold`` on the gradient magnitude of
        [0, 1] images); or ``"dog"`` — difference of Gaussians ``D = G_σ * L − G_{kσ} * L``
        thresholded: a pixel is ink where ``D < −dog_threshold`` (darker than its surround, the
        classic DoG line drawing, Winnemöller et al. 2012 XDoG with a hard step), and on the
        inside of silhouettes where the alpha DoG exceeds ``dog_threshold``. DoG ink lies on
        the darker side of an edge (≈ 1–2 px off it for ``sigma=1``) and is 2–3 px wide.
    dilate : int >= 0, thicken lines by this many pixels (3×3 dilation repeated).
    channels : ``"luminance"`` (Rec. 709 luma) or ``"rgb"`` (luma + each of R, G, B).

    Returns
    -------
    (H, W) uint8: 0 on lines, 255 elsewhere.
    """
    from scipy import ndimage as ndi

    img = _as_float_image(image)
    if sigma <= 0:
        raise ValueError(f"sigma must be > 0 pixels, got {sigma}")
    if int(dilate) != dilate or dilate < 0:
        raise ValueError(f"dilate must be an integer >= 0, got {dilate!r}")
    if channels not in ("luminance", "rgb"):
        raise ValueError(f"channels must be 'luminance' or 'rgb', got {channels!r}")
    if method not in ("canny", "dog"):
        raise ValueError(f"method must be 'canny' or 'dog', got {method!r}")
    a = img[..., 3]
    flat = img[..., :3] * a[..., None] + (1.0 - a[..., None])          # over white
    planes = [flat @ _LUMA]                                            # (H, W) each
    if channels == "rgb":
        planes += [flat[..., k] for k in range(3)]
    lines = np.zeros(a.shape, bool)
    if method == "canny":
        from skimage.feature import canny

        for f in planes + ([a] if a.min() < 1.0 else []):
            lines |= canny(f, sigma=sigma, low_threshold=low_threshold,
                           high_threshold=high_threshold, mode="nearest")
    else:
        def dog(f):
            return (ndi.gaussian_filter(f, sigma, mode="nearest")
                    - ndi.gaussian_filter(f, dog_k * sigma, mode="nearest"))

        for f in planes:
            lines |= dog(f) < -dog_threshold
        if a.min() < 1.0:
            lines |= dog(a) > dog_threshold
    if dilate:
        lines = ndi.binary_dilation(lines, np.ones((3, 3), bool), iterations=int(dilate))
    return np.where(lines, 0, 255).astype(np.uint8)


# ------------------------------------------------------------------------------ renderers
@runtime_checkable
class Renderer(Protocol):
    """Anything that turns simulated vertex positions into frames.

    ``render(frame_index, positions)`` → (H, W, 3) uint8, where ``positions`` is a list with
    one (n_b, 2) float array of deformed vertex positions (output pixels, y down) per body,
    in the body order the renderer was built with. ``frame_index`` (int, 0-based) lets a
    renderer use per-frame state: :class:`WarpRenderer` uses it for per-frame depth; a
    sketch-guided video diffusion renderer (PhysAnimator's ToonCrafter + ControlNet) would
    take the first frame and the per-frame control images (:func:`edge_map`) and return its
    repainted frame ``frame_index``.
    """

    def render(self, frame_index: int, positions: Sequence[np.ndarray]) -> np.ndarray: ...


class WarpRenderer:
    """CPU renderer: warps each body's drawing by its simulated mesh (:func:`render_bodies`).

    Parameters
    ----------
    textures : list of B textures, (Ht, Wt, 3|4) uint8 or float in [0, 1].
    X_list : list of B (n_b, 2) float texture coordinates (texture pixels).
    tris_list : list of B (T_b, 3) int triangles.
    size : (H, W) output size in pixels.
    depth : None (list order, first at the back), (B,) floats, or (n_frames, B) floats (row
        ``frame_index`` is used); larger depth = further back.
    background, supersample : see :func:`render_bodies`.
    control : if True, :meth:`render_sequence` also returns the control images.
    edge_kwargs : dict of keyword arguments for :func:`edge_map` (e.g. ``method="dog"``).

    The textures are prepared (premultiplied, magnified) once, at construction.
    """

    def __init__(self, textures, X_list, tris_list, size, depth=None, background=(1, 1, 1),
                 supersample=2, control=False, edge_kwargs=None):
        _check_bodies(textures, X_list, tris_list)
        self.size = _check_size(size, "size")
        self.supersample = _check_supersample(supersample)
        self.X_list = [_check_points(X, f"X_list[{b}]") for b, X in enumerate(X_list)]
        self.tris_list = [_check_tris(t, len(X)) for t, X in zip(tris_list, self.X_list)]
        self._tex = [_prepare_texture(t, self.supersample) for t in textures]
        self.depth = None if depth is None else np.asarray(depth, dtype=float)
        B = len(self._tex)
        if self.depth is not None and (self.depth.ndim not in (1, 2) or self.depth.shape[-1] != B):
            raise ValueError(
                f"depth must have shape ({B},) or (n_frames, {B}), got {self.depth.shape}")
        _background_canvas(background, self.size)  # validate now, fail early
        self.background = background
        self.control = bool(control)
        self.edge_kwargs = dict(edge_kwargs or {})
        self._cache = None  # (frame_index, positions bytes, layers) of the last frame

    def _depth_at(self, frame_index):
        if self.depth is None or self.depth.ndim == 1:
            return self.depth
        if not 0 <= frame_index < len(self.depth):
            raise ValueError(
                f"frame_index {frame_index} outside the {len(self.depth)} frames of depth")
        return self.depth[frame_index]

    def layers(self, frame_index, positions):
        """Straight-alpha RGBA layers (H, W, 4) float32, back to front, for one frame."""
        if len(positions) != len(self._tex):
            raise ValueError(f"positions must hold one (n_b, 2) array per body ({len(self._tex)}), "
                             f"got {len(positions)}")
        xs = [_check_points(x, f"positions[{b}]", len(X))
              for b, (x, X) in enumerate(zip(positions, self.X_list))]
        key = (frame_index, b"".join(x.tobytes() for x in xs))
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        H, W = self.size
        layers = [_warp_prepared(self._tex[b], self.X_list[b], xs[b], self.tris_list[b], H, W,
                                 self.supersample)
                  for b in _back_to_front(self._depth_at(frame_index), len(self._tex))]
        self._cache = (key, layers)
        return layers

    def render(self, frame_index, positions):
        """(H, W, 3) uint8 frame; ``positions`` is a list of (n_b, 2) arrays, one per body."""
        return composite(self.layers(frame_index, positions), self.background, self.size,
                         dtype=np.uint8)

    def render_control(self, frame_index, positions):
        """(H, W) uint8 control image (dark lines on white) of the frame: :func:`edge_map` of
        the bodies composited over a transparent canvas (so silhouettes count as edges)."""
        rgba = _over_rgba(self.layers(frame_index, positions), self.size)
        return edge_map(rgba, **self.edge_kwargs)

    def render_sequence(self, positions_seq, progress=False):
        """Render frames ``0..n-1``; ``positions_seq[i]`` is the ``positions`` of frame i.

        Returns (n, H, W, 3) uint8 frames, and with ``control=True`` also the (n, H, W) uint8
        control images as a second value.
        """
        from tqdm.auto import tqdm

        frames, controls = [], []
        for i, pos in enumerate(tqdm(positions_seq, disable=not progress, desc="render")):
            frames.append(self.render(i, pos))
            if self.control:
                controls.append(self.render_control(i, pos))
        H, W = self.size
        frames = np.stack(frames) if frames else np.zeros((0, H, W, 3), np.uint8)
        if not self.control:
            return frames
        return frames, (np.stack(controls) if controls else np.zeros((0, H, W), np.uint8))


# ------------------------------------------------------------------------------- outputs
#: Largest frame rate the writers accept (frames per second).
MAX_FPS = 1000.0
#: Highest frame rate :func:`frames_to_gif` writes (20 ms frames).
MAX_GIF_FPS = 50.0


def _check_fps(fps):
    """``fps`` as a float in (0, :data:`MAX_FPS`]; ValueError naming it otherwise."""
    if isinstance(fps, bool) or not isinstance(fps, (int, float, np.integer, np.floating)) \
            or not np.isfinite(fps) or not 0 < fps <= MAX_FPS:
        raise ValueError(f"fps must be a number in (0, {MAX_FPS:g}] frames per second, got "
                         f"{fps!r}")
    return float(fps)


def _frames_uint8(frames):
    """Frames as ``(T, H, W, 3|4)`` uint8 by :func:`physlab.image.to_uint8`: uint8 as is, bool
    as 0/255, uint16 by its value range (round(x / 257)), float clipped to [0, 1];
    ``(T, H, W)`` grey gets three channels. ValueError naming what is wrong (shape, dtype,
    NaN/inf and the first frame holding one)."""
    f = np.asarray(frames)
    if f.ndim == 3:  # (T, H, W) grey
        f = np.repeat(f[..., None], 3, axis=3)
    if f.ndim != 4 or f.shape[3] not in (3, 4) or 0 in f.shape:
        raise ValueError(f"frames must have shape (T, H, W, 3|4) with T, H, W >= 1, got "
                         f"{f.shape}")
    if np.issubdtype(f.dtype, np.floating):
        bad = ~np.isfinite(f)
        if bad.any():
            t = int(np.argwhere(bad)[0][0])
            raise ValueError(f"frames hold {int(bad.sum())} NaN/inf values (first in frame "
                             f"{t}); fix the renderer's output before writing a video")
    return to_uint8(f, "frames", clip=True)


def frames_to_gif(frames, path, fps=20):
    """Write (T, H, W, 3|4) uint8 (or float in [0, 1]) frames to an animated, looping GIF.

    Written with imageio, looping; the file appears atomically. GIF frame times are whole
    centiseconds, so a rate that does not divide 100 (30 fps: 33.3 ms) gets frame times that
    alternate (30, 30, 40 ms) to keep the total ``T / fps`` to 10 ms (a constant 30 ms
    would play 10 % fast). Returns the Path.
    """
    import imageio.v3 as iio

    f = _frames_uint8(frames)
    fps = _check_fps(fps)
    if fps > MAX_GIF_FPS:
        raise ValueError(f"fps must be at most {MAX_GIF_FPS:g} for a GIF (its frame times are "
                         f"whole centiseconds and browsers slow down frames under 20 ms), got "
                         f"{fps:g}: write an MP4 (frames_to_mp4) for faster rates")
    ends = np.rint(np.arange(1, len(f) + 1) * 100.0 / fps)             # centiseconds
    durations = (np.diff(ends, prepend=0.0) * 10).astype(int).tolist()  # ms, multiples of 10
    return atomic_write(path, lambda tmp: iio.imwrite(tmp, f, duration=durations, loop=0),
                        ".gif")


def _last_line(e):
    """``"Type: last non-empty line"`` of an exception (ffmpeg errors carry its banner)."""
    lines = [ln.strip() for ln in str(e).splitlines() if ln.strip()]
    return f"{type(e).__name__}: {lines[-1][:200]}" if lines else type(e).__name__


def _write_mp4(f, path, fps, crf):
    import imageio_ffmpeg

    T, H, W = f.shape[:3]
    f = f[..., :3]
    if H % 2 or W % 2:  # yuv420p needs even sizes: pad by replicating the last row/column
        f = np.pad(f, ((0, 0), (0, H % 2), (0, W % 2), (0, 0)), mode="edge")
    writer = imageio_ffmpeg.write_frames(
        str(path), (f.shape[2], f.shape[1]), fps=fps, codec="libx264", pix_fmt_in="rgb24",
        pix_fmt_out="yuv420p", macro_block_size=1, quality=None,
        output_params=["-crf", str(int(crf)), "-preset", "medium", "-movflags", "+faststart",
                       "-f", "mp4"],
        ffmpeg_log_level="error")
    try:
        writer.send(None)  # start ffmpeg
        for frame in f:
            writer.send(np.ascontiguousarray(frame))
        writer.close()
    except Exception as e:  # noqa: BLE001 - a dead ffmpeg surfaces as OSError/BrokenPipe/...
        raise RuntimeError(f"ffmpeg failed while writing the MP4 ({_last_line(e)}); disk "
                           f"full or a file-size limit?") from None
    # ffmpeg can exit early (killed, disk full) without the pipe reporting it: read the file
    # back and insist on every frame before it replaces the target.
    try:
        n, _ = imageio_ffmpeg.count_frames_and_secs(str(path))
    except Exception as e:  # noqa: BLE001
        raise RuntimeError(f"ffmpeg wrote an unreadable MP4 ({_last_line(e)}); disk full or "
                           f"a file-size limit?") from None
    if n != T:
        raise RuntimeError(f"ffmpeg wrote {n} of {T} frames; disk full or a file-size limit?")


def frames_to_mp4(frames, path, fps=24, crf=23):
    """Write frames (T, H, W, 3|4) uint8 or float in [0, 1] to an H.264 MP4 (yuv420p).

    Uses the ffmpeg binary shipped with imageio-ffmpeg; ``crf`` is x264's constant rate
    factor (18 ≈ visually lossless, 23 default, 28 small). Alpha is dropped; odd sizes are
    padded to even by one replicated row/column (yuv420p requires it). The file appears
    atomically. Returns the Path.
    """
    f = _frames_uint8(frames)
    fps = _check_fps(fps)
    if isinstance(crf, bool) or not isinstance(crf, (int, float)) or not 0 <= crf <= 51:
        raise ValueError(f"crf must be a number in 0..51 (x264's quality scale), got {crf!r}")
    try:
        return atomic_write(path, lambda tmp: _write_mp4(f, tmp, fps, crf), ".mp4")
    except RuntimeError as e:
        raise RuntimeError(f"could not write {path}: {e}; the previous file (if any) is "
                           f"unchanged") from None


def frames_to_html(frames, fps=24, fmt="video", crf=25, width=None):
    """Inline animation for notebooks: :class:`IPython.display.HTML`.

    ``fmt="video"``: base64 H.264 MP4 in a looping ``<video>`` (small; needs the ffmpeg of
    imageio-ffmpeg, else falls back to GIF); ``fmt="gif"``: base64 animated GIF in an
    ``<img>``. ``width``: display width in CSS pixels (default: the frame width).
    """
    from IPython.display import HTML

    f = _frames_uint8(frames)
    if fmt not in ("video", "gif"):
        raise ValueError(f"fmt must be 'video' or 'gif', got {fmt!r}")
    width = int(width or f.shape[2])
    with tempfile.TemporaryDirectory() as d:
        video = None
        if fmt == "video":
            try:
                video = frames_to_mp4(f, Path(d) / "anim.mp4", fps=fps, crf=crf)
            except (RuntimeError, OSError, ImportError):  # no usable ffmpeg: GIF below
                video = None
        if video is not None:
            data = base64.b64encode(video.read_bytes()).decode("ascii")
            return HTML(f'<video width="{width}" controls autoplay loop muted playsinline>'
                        f'<source type="video/mp4" src="data:video/mp4;base64,{data}">'
                        "</video>")
        p = frames_to_gif(f, Path(d) / "anim.gif", fps=fps)
        data = base64.b64encode(p.read_bytes()).decode("ascii")
        return HTML(f'<img width="{width}" src="data:image/gif;base64,{data}">')
