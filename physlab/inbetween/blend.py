"""Blending optimisation: the image matrix I(α, t) and its cheapest path.

Brodt & Bessmeltsev 2024, Sec. 5.2 and Fig. 9.

At every time ``t_i`` (``t = linspace(0, 1, n_t)``) the skeletal pipeline gives two frames
in the same pose, ``I→(t)`` (texture of key 0) and ``I←(t)`` (texture of key 1). A frame
interpolator fills the row ``I(α, t) = F(I→(t), I←(t), α)`` (:func:`image_matrix`), and the
final animation is a path through the matrix from ``I(0, 0) = key 0`` to ``I(1, 1) = key 1``
with one image per row (:func:`blending_path`). The naive path is the diagonal ``α = t``.

The graph
---------
One vertex per image ``(t_i, α_k)``; edges only from row ``i`` to row ``i + 1``, from ``α_k``
to every ``α_m`` with ``α_k ≤ α_m ≤ α_k + ε``. The paper allows ``|α_k − α_m| < ε`` (going
back is possible); physlab restricts to **non-decreasing** α — the blend never returns to a
texture it is leaving, which is also what the animation should do. With ``n_t`` rows a path
from α = 0 to α = 1 exists only if ``ε ≥ 1/(n_t − 1)``; the paper's ``ε = 0.02`` assumes
≥ 51 rows, so physlab ties ε to the frame count (:func:`alpha_grid`).

Costs: the paper's literal form, and physlab's reading
-------------------------------------------------------
Paper: vertex cost ``q(α, t)`` (texture quality, an IoU, linearly interpolated in α) and edge
cost ``½(Q(t) + Q(t+1))`` with ``Q(t) = ∫ |div v(t)|²`` of the interpolator's flow. Taken
literally neither depends on *where* a path moves in α: in the no-occlusion case q ≡ 1, the
edge cost is the same for every α, and *every monotone path costs the same* (and where q < 1
a high q is *good*, so it would have to enter as a penalty ``1 − q``). physlab therefore uses

* vertex cost (weighted by ``Δt`` so the sum approximates ``∫ c dt``), by default the
  **variance model** (``texture_model="variance"``)::

      c(α, t) = [(1 − α)² σ→²(t) + α² σ←²(t)] / max σ² + λ_mid · 4α(1 − α) + λ_diag · |α − t|
      σ→²(t)  = d→(t) + prior · t,     σ←²(t) = d←(t) + prior · (1 − t)
      d(t)    = (1 − q(t)) + λ_dist · D(t)

  — the error variance of the blend ``(1 − α) I→ + α I←`` of two aligned images whose texture
  errors are independent with variances σ², minimised by ``α* = σ→² / (σ→² + σ←²)``. ``D(t) ≥ 0``
  is a per-frame texture distortion supplied by the caller (the deformation's mean
  symmetric-Dirichlet excess ``E_d/4 − 1``, zero for rigid motion) and ``1 − q`` the inpainted
  fraction (:func:`texture_quality`; the pipeline measures it on the visible pixels of the
  layered templates' inpainted texels, :meth:`~physlab.inbetween.occlusion.LayeredTemplate.
  render_inpainted`): use more of the keyframe whose texture is less inpainted and less
  stretched, but keep blending, which averages independent errors away. With no information
  (``d = 0``) the distance prior gives ``α* = t``, the diagonal. The alternative
  ``texture_model="linear"``, ``c = (1 − α) d→ + α d←``, is linear in α, so its cheapest path
  sits on one texture and switches as fast as ε allows; on the ground-truth benchmark
  (``physlab.inbetween.evaluate``) it loses to the diagonal, the variance model beats it.
  ``λ_mid`` (default 0) penalises mid-blend frames; ``λ_diag`` (default 1e-3) breaks ties
  towards the diagonal.
* edge cost ``λ_Q · ½(Q̂(t_i) + Q̂(t_{i+1})) · |α_m − α_k|`` with ``Q̂ = Q / max Q``: moving
  along α is where the interpolation model is used, so the transition is pushed to the rows
  whose flow is most incompressible. Every monotone path travels ``Σ|Δα| = 1``, so this term
  only decides *where* the blend happens. (The pipeline uses λ_Q = 0.1: on drawings with
  different textures much of the flow's divergence is noise.)

The shortest path is found with Dijkstra (scipy), as in the paper.
"""
from __future__ import annotations

import inspect
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from .frame_interpolation import FlowInterpolator, as_image

__all__ = [
    "ImageMatrix", "image_matrix", "row_flows", "render_path",
    "interpolation_quality", "texture_quality",
    "alpha_grid", "BlendCosts", "blend_costs", "BlendPath", "blending_path",
    "diagonal_path", "path_cost", "select_frames",
]

_TOL = 1e-9              # slack in α comparisons (grid values are floats)
_WARN_BYTES = 2 << 30    # image_matrix warns above this size


# --------------------------------------------------------------------------- the matrix
@dataclass(frozen=True, eq=False)
class ImageMatrix:
    """The matrix of images I(α, t) of Brodt & Bessmeltsev 2024, Fig. 9a.

    Attributes
    ----------
    images : (n_t, n_α, H, W, C) float32, ``images[i, k] = I(alphas[k], t[i])``; straight RGBA
        or RGB. ``images[i, 0] = I→(t_i)``, ``images[i, -1] = I←(t_i)``.
    alphas : (n_α,) float64, increasing from 0 to 1.
    t : (n_t,) float64, ``linspace(0, 1, n_t)``.
    flows : (n_t, H, W, 2) float32, the interpolator's flow ``I→(t_i) → I←(t_i)`` in pixels.
    """

    images: np.ndarray
    alphas: np.ndarray
    t: np.ndarray
    flows: np.ndarray

    @property
    def shape(self):
        """(n_t, n_α)."""
        return self.images.shape[:2]


def _check_sequences(fwd, bwd):
    """-> (n_t, H, W, C) float32 pair, validated."""
    def seq(x, name):
        if isinstance(x, np.ndarray) and x.ndim == 4:
            frames = list(x)
        elif isinstance(x, np.ndarray):
            raise ValueError(f"{name} must be (n_t, H, W, C) or a list of (H, W, C) images, "
                             f"got shape {x.shape}")
        else:
            frames = list(x)
        if len(frames) < 2:
            raise ValueError(f"{name} needs at least 2 frames (t = 0 and t = 1), "
                             f"got {len(frames)}")
        return np.stack([as_image(f, f"{name}[{i}]") for i, f in enumerate(frames)])
    F, B = seq(fwd, "fwd"), seq(bwd, "bwd")
    if F.shape != B.shape:
        raise ValueError(f"fwd and bwd must have the same shape (n_t, H, W, C), got {F.shape} "
                         f"and {B.shape}")
    return F, B


def _check_grid(alphas):
    al = np.asarray(alphas, dtype=np.float64)
    if al.ndim != 1 or len(al) < 2:
        raise ValueError(f"alphas must be a 1-D array of ≥ 2 values, got shape {al.shape}")
    if not np.isfinite(al).all():
        raise ValueError("alphas contain NaN or inf")
    if abs(al[0]) > _TOL or abs(al[-1] - 1) > _TOL or np.any(np.diff(al) <= 0):
        raise ValueError(f"alphas must increase strictly from 0 to 1, got "
                         f"[{al[0]:g}, …, {al[-1]:g}] (n={len(al)}); use alpha_grid(n_t)")
    al = al.copy()
    al[0], al[-1] = 0.0, 1.0
    return al


def _progress(it, progress, desc, total=None):
    if not progress:
        return it
    from tqdm.auto import tqdm
    return tqdm(it, desc=desc, total=total)


def image_matrix(fwd, bwd, alphas, interpolator=None, progress=False):
    """Interpolate every row ``(I→(t_i), I←(t_i))`` at every α (Brodt & Bessmeltsev 2024, Fig. 9a).

    Parameters
    ----------
    fwd : (n_t, H, W, C) array or list of n_t images, ``I→(t)`` (texture of key 0).
    bwd : same shape, ``I←(t)`` (texture of key 1).
    alphas : (n_α,) increasing from 0 to 1, e.g. ``alpha_grid(n_t)[0]``.
    interpolator : a :class:`~physlab.inbetween.frame_interpolation.FrameInterpolator`; default
        ``FlowInterpolator()``. If it has ``interpolate_and_flow`` a row costs two flow
        estimates, otherwise three (``__call__`` and ``flow``).
    progress : bool, tqdm bar over rows.

    Returns
    -------
    :class:`ImageMatrix`; ``images`` is ``n_t·n_α·H·W·C·4`` bytes (1.4 GB for 11 × 31 frames
    of 512² RGBA) — when only the chosen frames are needed use :func:`row_flows`,
    :func:`blending_path` on :func:`blend_costs` and :func:`render_path` instead.
    """
    F, B = _check_sequences(fwd, bwd)
    al = _check_grid(alphas)
    interp = FlowInterpolator() if interpolator is None else interpolator
    n_t, H, W, C = F.shape
    nbytes = n_t * len(al) * H * W * C * 4
    if nbytes > _WARN_BYTES:
        warnings.warn(f"image_matrix will hold {nbytes / 2**30:.1f} GiB of float32 images; "
                      f"use row_flows + blending_path + render_path to keep only the path",
                      stacklevel=2)
    images = np.empty((n_t, len(al), H, W, C), np.float32)           # (n_t, n_α, H, W, C)
    flows = np.empty((n_t, H, W, 2), np.float32)
    both = getattr(interp, "interpolate_and_flow", None)
    takes_out = both is not None and "out" in inspect.signature(both).parameters
    for i in _progress(range(n_t), progress, "image matrix"):
        if takes_out:                                   # frames written in place
            flows[i] = both(F[i], B[i], al, out=images[i])[1]
        elif both is not None:
            images[i], flows[i] = both(F[i], B[i], al)
        else:
            images[i], flows[i] = interp(F[i], B[i], al), interp.flow(F[i], B[i])
    return ImageMatrix(images=images, alphas=al, t=np.linspace(0.0, 1.0, n_t), flows=flows)


def row_flows(fwd, bwd, interpolator=None, progress=False):
    """The flow ``I→(t_i) → I←(t_i)`` of every row, without interpolating any image.

    Parameters
    ----------
    fwd, bwd : (n_t, H, W, C) arrays or lists of images (as in :func:`image_matrix`).
    interpolator : FrameInterpolator, default ``FlowInterpolator()``.

    Returns
    -------
    (n_t, H, W, 2) float32 flows in pixels.
    """
    F, B = _check_sequences(fwd, bwd)
    interp = FlowInterpolator() if interpolator is None else interpolator
    return np.stack([interp.flow(F[i], B[i])
                     for i in _progress(range(len(F)), progress, "flows")]).astype(np.float32)


def render_path(fwd, bwd, path, interpolator=None, progress=False):
    """Only the frames on a path: ``I(α_i, t_i) = F(I→(t_i), I←(t_i), α_i)``.

    Parameters
    ----------
    fwd, bwd : (n_t, H, W, C) arrays or lists of images.
    path : :class:`BlendPath` or (n_t,) array of α values in [0, 1].
    interpolator : FrameInterpolator, default ``FlowInterpolator()``.

    Returns
    -------
    (n_t, H, W, C) float32; equals ``select_frames(image_matrix(...), path)``.
    """
    F, B = _check_sequences(fwd, bwd)
    al = np.asarray(path.alphas if isinstance(path, BlendPath) else path, dtype=np.float64)
    if al.shape != (len(F),):
        raise ValueError(f"path has {al.shape} α values, expected ({len(F)},), one per row")
    interp = FlowInterpolator() if interpolator is None else interpolator
    return np.stack([interp(F[i], B[i], al[i:i + 1])[0]
                     for i in _progress(range(len(F)), progress, "path frames")])


# --------------------------------------------------------------------------- quality terms
def interpolation_quality(flow, mask=None):
    """Compressibility of a flow: ``Q = mean_p |div v(p)|²`` (Brodt & Bessmeltsev 2024, Sec. 5.2).

    The paper's ``Q(t) = ∫_I |div v(t)|²``; physlab normalises the integral by the number of
    pixels (mean over the image, or over ``mask``), so Q does not grow with the image size.
    With ``v`` in px and derivatives per px, ``div v`` is dimensionless and so is Q (the
    paper's integral is ``Q × pixel count``, in px²). ``div v = ∂v_x/∂x + ∂v_y/∂y`` by
    central differences (``np.gradient``, one-sided at the border). Zero for translations
    and rotations, ``4 s²`` for a uniform scaling ``v = s·(x − c)``.

    Parameters
    ----------
    flow : (H, W, 2) or (n, H, W, 2) float, pixels ``(x, y)``.
    mask : optional (H, W) or (n, H, W) bool, pixels to average over (e.g. the foreground);
        an empty mask gives Q = 0.

    Returns
    -------
    float, or (n,) float64 for a stack of flows.
    """
    v = np.asarray(flow, dtype=np.float64)
    if v.ndim not in (3, 4) or v.shape[-1] != 2:
        raise ValueError(f"flow must have shape (H, W, 2) or (n, H, W, 2), got {v.shape}")
    if not np.isfinite(v).all():
        raise ValueError("flow contains NaN or inf")
    if min(v.shape[-3:-1]) < 2:
        raise ValueError(f"flow must be at least 2×2 pixels, got {v.shape[-3:-1]}")
    div = np.gradient(v[..., 0], axis=-1) + np.gradient(v[..., 1], axis=-2)   # Eq. in Sec. 5.2
    div2 = div ** 2
    if mask is None:
        Q = div2.mean(axis=(-2, -1))
    else:
        m = np.asarray(mask, dtype=bool)
        if m.shape != div2.shape:
            raise ValueError(f"mask must have shape {div2.shape}, got {m.shape}")
        n = m.sum(axis=(-2, -1))
        Q = np.where(n > 0, (div2 * m).sum(axis=(-2, -1)) / np.maximum(n, 1), 0.0)
    return float(Q) if np.ndim(Q) == 0 else Q


def texture_quality(inpainted=None, foreground=None, n_t=None):
    """Texture quality q(t): IoU of the original (not inpainted) texture with the visible shape.

    Brodt & Bessmeltsev 2024, Sec. 5.2 define q as "the IoU of the inpainted area in that
    pose", 1 at the frame's own keyframe. physlab's reading: with ``F`` the visible foreground
    and ``A`` the inpainted pixels visible in it, the original texture covers ``F \\ A`` and
    ``q = IoU(F \\ A, F) = 1 − |A ∩ F| / |F|`` (1 = no inpainting visible).

    Parameters
    ----------
    inpainted : None, or (n_t, H, W) bool / list of n_t (H, W) masks (entries may be None),
        the pixels of the deformed frame whose texture came from inpainting.
    foreground : (n_t, H, W) bool or list of masks, the visible silhouette (e.g. alpha > 0.5);
        required where ``inpainted`` is given.
    n_t : int, number of frames when ``inpainted`` is None.

    Returns
    -------
    (n_t,) float64 in [0, 1]; all ones when ``inpainted`` is None (no occlusion handling).
    """
    if inpainted is None:
        if n_t is None:
            if foreground is None:
                raise ValueError("texture_quality needs inpainted masks, foreground masks or "
                                 "n_t")
            n_t = len(foreground)
        return np.ones(int(n_t))
    if foreground is None:
        raise ValueError("texture_quality(inpainted, foreground): the foreground masks are "
                         "needed to normalise the inpainted area (pass alpha > 0.5)")
    if len(foreground) != len(inpainted):
        raise ValueError(f"inpainted has {len(inpainted)} masks but foreground "
                         f"{len(foreground)}")
    q = np.ones(len(inpainted))
    for i, (A, Fg) in enumerate(zip(inpainted, foreground)):
        if A is None:
            continue
        A, Fg = np.asarray(A, dtype=bool), np.asarray(Fg, dtype=bool)
        if A.shape != Fg.shape:
            raise ValueError(f"inpainted[{i}] has shape {A.shape}, foreground[{i}] {Fg.shape}")
        nF = Fg.sum()
        q[i] = 1.0 - (A & Fg).sum() / nF if nF else 1.0
    return q


# --------------------------------------------------------------------------- the α grid
def alpha_grid(n_frames, speedup=3, subdivisions=None):
    """An α grid and smoothness bound ε consistent with ``n_frames`` rows.

    A monotone path needs ``(n_frames − 1)·ε ≥ 1``; the diagonal moves α by ``1/(n_frames−1)``
    per row. physlab sets ``ε = min(1, speedup/(n_frames − 1))``: the blend may run up to
    ``speedup`` times faster than the diagonal (the paper's ε = 0.02 with many rows is the
    same idea). The grid spacing is ``h = 1/((n_frames − 1)·subdivisions)``, so the grid
    contains every diagonal value ``t_i = i/(n_frames − 1)`` (the diagonal is a valid path) and
    ``ε/h`` is an integer (α can move by exactly ε).

    Parameters
    ----------
    n_frames : int ≥ 2, number of rows n_t.
    speedup : float ≥ 1; ``speedup·subdivisions`` must be an integer.
    subdivisions : int ≥ 1, grid points per diagonal step; default ``max(1, round(speedup))``
        (31 α values for 11 frames with speedup 3).

    Returns
    -------
    alphas : ((n_frames − 1)·subdivisions + 1,) float64, ``linspace(0, 1, ·)``.
    eps : float.
    """
    n = int(n_frames)
    if n != n_frames or n < 2:
        raise ValueError(f"n_frames must be an integer ≥ 2, got {n_frames}")
    if not np.isfinite(speedup) or speedup < 1:
        raise ValueError(f"speedup must be ≥ 1 (ε ≥ 1/(n_frames − 1) is needed for a path), "
                         f"got {speedup}")
    m = max(1, round(speedup)) if subdivisions is None else int(subdivisions)
    if m < 1 or (subdivisions is not None and m != subdivisions):
        raise ValueError(f"subdivisions must be an integer ≥ 1, got {subdivisions}")
    eps = min(1.0, speedup / (n - 1))
    steps = eps * (n - 1) * m                     # ε / h
    if abs(steps - round(steps)) > 1e-9:
        raise ValueError(f"ε = speedup/(n_frames − 1) must be a multiple of the grid spacing; "
                         f"speedup·subdivisions = {speedup * m:g} is not an integer (pick an "
                         f"integer speedup or a matching subdivisions)")
    return np.linspace(0.0, 1.0, (n - 1) * m + 1), float(eps)


# --------------------------------------------------------------------------- costs
@dataclass(frozen=True, eq=False)
class BlendCosts:
    """Costs of the blending graph.

    The cost of a path ``k_0 … k_{n_t−1}`` (one α index per row) is
    ``Σ_i vertex[i, k_i] + Σ_i move[i] · |alphas[k_{i+1}] − alphas[k_i]|``.

    Attributes
    ----------
    vertex : (n_t, n_α) float, cost of using image ``(t_i, α_k)``.
    move : (n_t − 1,) float, cost per unit of α moved between rows i and i + 1 (≥ 0 in
        physlab's costs; any sign is accepted).
    alphas : (n_α,) float, increasing from 0 to 1.
    """

    vertex: np.ndarray
    move: np.ndarray
    alphas: np.ndarray

    def __post_init__(self):
        V = np.asarray(self.vertex, dtype=np.float64)
        al = _check_grid(self.alphas)
        if V.ndim != 2 or V.shape[0] < 2 or V.shape[1] != len(al):
            raise ValueError(f"vertex must have shape (n_t ≥ 2, n_α = {len(al)}), got {V.shape}")
        mv = np.asarray(self.move, dtype=np.float64)
        if mv.ndim == 0:                                              # one value for all rows
            mv = np.full(V.shape[0] - 1, float(mv))
        if mv.shape != (V.shape[0] - 1,):
            raise ValueError(f"move must have shape ({V.shape[0] - 1},) (one per pair of rows), "
                             f"got {mv.shape}")
        if not (np.isfinite(V).all() and np.isfinite(mv).all()):
            raise ValueError("costs contain NaN or inf")
        object.__setattr__(self, "vertex", V)
        object.__setattr__(self, "move", mv)
        object.__setattr__(self, "alphas", al)

    @property
    def n_t(self):
        return self.vertex.shape[0]


def _per_row(x, n_t, name, default):
    if x is None:
        return np.full(n_t, float(default))
    a = np.asarray(x, dtype=np.float64)
    if a.shape != (n_t,):
        raise ValueError(f"{name} must have shape ({n_t},) (one value per row), got {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} contains NaN or inf")
    return a


TEXTURE_MODELS = ("variance", "linear")


def blend_costs(alphas, n_t=None, Q=None, q_fwd=None, q_bwd=None, distortion_fwd=None,
                distortion_bwd=None, lambda_Q=1.0, lambda_dist=1.0, lambda_mid=0.0,
                lambda_diag=1e-3, texture_model="variance", prior=0.01):
    """physlab's blending costs (module docstring; Brodt & Bessmeltsev 2024, Sec. 5.2).

    Two readings of the texture term (``texture_model``):

    * ``"linear"``: ``c = (1 − α) d→(t) + α d←(t)`` — linear in α, so the cheapest path
      sits on one keyframe's texture and switches as fast as ε allows;
    * ``"variance"``: the blend ``(1 − α) I→ + α I←`` of two aligned images with independent
      texture errors of variances ``σ→²``, ``σ←²`` has error variance
      ``(1 − α)² σ→² + α² σ←²``, minimised by ``α* = σ→² / (σ→² + σ←²)`` — a blend
      that leans on the better texture without discarding the other. ``σ² = d + prior·s``
      with ``s = t`` for I→ and ``1 − t`` for I← (a texture degrades with the distance from
      its keyframe), so with no distortion information ``α* = t``, the diagonal. The term is
      divided by its largest value so that the weights stay scale-free.

    Parameters
    ----------
    alphas : (n_α,) grid, increasing from 0 to 1.
    n_t : int, number of rows; inferred from the per-row arrays when omitted.
    Q : (n_t,) interpolation quality per row (:func:`interpolation_quality`), ≥ 0; normalised
        by its maximum. None: 0 (the Q term vanishes).
    q_fwd, q_bwd : (n_t,) texture quality of I→(t) and I←(t) in [0, 1]
        (:func:`texture_quality`); None: 1.
    distortion_fwd, distortion_bwd : (n_t,) texture distortion D(t) ≥ 0 of each deformed
        sequence (mean symmetric-Dirichlet excess ``E_d/4 − 1``); None: 0.
    lambda_Q, lambda_dist, lambda_mid, lambda_diag : float ≥ 0, weights (defaults 1, 1, 0,
        1e-3).
    texture_model : "variance" (default) or "linear" (above).
    prior : float > 0, the distance prior of the variance model (in units of ``d``).

    Returns
    -------
    :class:`BlendCosts` with ``vertex[i, k] = Δt · c(α_k, t_i)`` and
    ``move[i] = λ_Q · ½(Q̂_i + Q̂_{i+1})``.
    """
    al = _check_grid(alphas)
    given = [x for x in (Q, q_fwd, q_bwd, distortion_fwd, distortion_bwd) if x is not None]
    if n_t is None:
        if not given:
            raise ValueError("blend_costs needs n_t or at least one per-row array")
        n_t = len(np.atleast_1d(given[0]))
    n_t = int(n_t)
    if n_t < 2:
        raise ValueError(f"n_t must be ≥ 2, got {n_t}")
    for name, lam in (("lambda_Q", lambda_Q), ("lambda_dist", lambda_dist),
                      ("lambda_mid", lambda_mid), ("lambda_diag", lambda_diag)):
        if not (np.isfinite(lam) and lam >= 0):
            raise ValueError(f"{name} must be a finite number ≥ 0, got {lam}")
    Q = _per_row(Q, n_t, "Q", 0.0)
    qf, qb = _per_row(q_fwd, n_t, "q_fwd", 1.0), _per_row(q_bwd, n_t, "q_bwd", 1.0)
    Df = _per_row(distortion_fwd, n_t, "distortion_fwd", 0.0)
    Db = _per_row(distortion_bwd, n_t, "distortion_bwd", 0.0)
    if Q.min() < 0 or Df.min() < 0 or Db.min() < 0:
        raise ValueError("Q and the distortions must be ≥ 0")
    if qf.min() < 0 or qf.max() > 1 or qb.min() < 0 or qb.max() > 1:
        raise ValueError("texture qualities q_fwd, q_bwd must lie in [0, 1]")
    if texture_model not in TEXTURE_MODELS:
        raise ValueError(f"texture_model must be one of {TEXTURE_MODELS}, got {texture_model!r}")
    if not (np.isfinite(prior) and prior > 0):
        raise ValueError(f"prior must be a finite number > 0, got {prior}")
    t = np.linspace(0.0, 1.0, n_t)[:, None]                           # (n_t, 1)
    A = al[None, :]                                                   # (1, n_α)
    d_fwd = (1.0 - qf) + lambda_dist * Df                             # (n_t,)
    d_bwd = (1.0 - qb) + lambda_dist * Db
    if texture_model == "linear":
        tex = (1.0 - A) * d_fwd[:, None] + A * d_bwd[:, None]         # (n_t, n_α)
    else:
        v_fwd = d_fwd[:, None] + prior * t                            # σ→², (n_t, 1)
        v_bwd = d_bwd[:, None] + prior * (1.0 - t)                    # σ←²
        tex = (1.0 - A) ** 2 * v_fwd + A ** 2 * v_bwd
        tex = tex / max(float(np.max(np.maximum(v_fwd, v_bwd))), 1e-300)
    c = tex + lambda_mid * 4.0 * A * (1.0 - A) + lambda_diag * np.abs(A - t)
    Qn = Q / Q.max() if Q.max() > 0 else Q
    move = lambda_Q * 0.5 * (Qn[:-1] + Qn[1:])                        # (n_t − 1,)
    return BlendCosts(vertex=c / (n_t - 1), move=move, alphas=al)


def _foreground(images, threshold=0.5):
    """(n_t, n_α, H, W, C) matrix -> (n_t, H, W) bool union of the two ends' silhouettes."""
    if images.shape[-1] != 4:
        return None
    return (images[:, 0, ..., 3] > threshold) | (images[:, -1, ..., 3] > threshold)


# --------------------------------------------------------------------------- paths
@dataclass(frozen=True, eq=False)
class BlendPath:
    """A path through the image matrix, one image per row.

    Attributes
    ----------
    alphas : (n_t,) float64, α of the chosen image in each row (0 first, 1 last).
    indices : (n_t,) int64, its column in the α grid.
    cost : float, the path's cost (:func:`path_cost`); NaN when no costs were given.
    diagonal_cost : float, cost of the diagonal α = t under the same costs (NaN if the
        diagonal is not on the grid or no costs were given).
    """

    alphas: np.ndarray
    indices: np.ndarray
    cost: float
    diagonal_cost: float


def _edges(alphas, eps):
    """All (k, m) with α_k ≤ α_m ≤ α_k + ε: two (E,) int arrays (same for every row)."""
    n = len(alphas)
    hi = np.searchsorted(alphas, alphas + eps + _TOL, side="right")   # exclusive end, (n,)
    counts = hi - np.arange(n)
    src = np.repeat(np.arange(n), counts)
    start = np.repeat(np.cumsum(counts) - counts, counts)
    dst = src + (np.arange(counts.sum()) - start)
    return src, dst


def path_cost(costs, indices):
    """Cost of a path (see :class:`BlendCosts`).

    Parameters
    ----------
    costs : :class:`BlendCosts`.
    indices : (n_t,) int, column of each row's image.

    Returns
    -------
    float.
    """
    idx = np.asarray(indices)
    if idx.shape != (costs.n_t,) or not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"indices must be ({costs.n_t},) ints, got {idx.dtype} {idx.shape}")
    if idx.min() < 0 or idx.max() >= len(costs.alphas):
        raise ValueError(f"indices must lie in [0, {len(costs.alphas)}), got "
                         f"[{idx.min()}, {idx.max()}]")
    a = costs.alphas[idx]
    return float(costs.vertex[np.arange(costs.n_t), idx].sum()
                 + np.sum(costs.move * np.abs(np.diff(a))))


def diagonal_path(n_t, alphas, costs=None):
    """The naive path α = t (the red diagonal of Brodt & Bessmeltsev 2024, Fig. 9a).

    Parameters
    ----------
    n_t : int ≥ 2.
    alphas : (n_α,) grid containing every ``i/(n_t − 1)`` (as :func:`alpha_grid` makes).
    costs : optional :class:`BlendCosts` to price it.

    Returns
    -------
    :class:`BlendPath` (``cost == diagonal_cost``; NaN without costs).
    """
    al = _check_grid(alphas)
    t = np.linspace(0.0, 1.0, int(n_t))
    idx = np.searchsorted(al, t - _TOL)
    idx = np.minimum(idx, len(al) - 1)
    if np.any(np.abs(al[idx] - t) > 1e-7):
        raise ValueError(f"the α grid does not contain every diagonal value i/{n_t - 1}; "
                         f"build it with alpha_grid({n_t})")
    c = np.nan if costs is None else path_cost(costs, idx)
    return BlendPath(alphas=al[idx], indices=idx.astype(np.int64), cost=c, diagonal_cost=c)


def _diagonal_cost(costs):
    try:
        return diagonal_path(costs.n_t, costs.alphas, costs).cost
    except ValueError:
        return np.nan


def blending_path(matrix_or_costs, eps, *, q_fwd=None, q_bwd=None, distortion_fwd=None,
                  distortion_bwd=None, lambda_Q=1.0, lambda_dist=1.0, lambda_mid=0.0,
                  lambda_diag=1e-3, texture_model="variance", prior=0.01,
                  foreground_only=True):
    """Cheapest monotone path from I(0, 0) to I(1, 1) (Brodt & Bessmeltsev 2024, Sec. 5.2).

    Graph: a vertex per image; edges from ``(t_i, α_k)`` to ``(t_{i+1}, α_m)`` for
    ``α_k ≤ α_m ≤ α_k + ε`` with weight ``move[i]·(α_m − α_k) + vertex[i+1, m]`` (the vertex
    costs moved onto the edges entering them; the start vertex's cost is added at the end).
    Solved with ``scipy.sparse.csgraph.dijkstra``. Every path has exactly ``n_t − 1`` edges,
    so a constant is added to every weight (all become > 0: dijkstra would drop explicit
    zero edges, and negative costs are allowed) and subtracted again — the argmin is unchanged.

    Parameters
    ----------
    matrix_or_costs : :class:`ImageMatrix` (costs built with :func:`blend_costs` from its flows,
        ``Q`` over the foreground when ``foreground_only``) or :class:`BlendCosts`.
    eps : float, largest α step between consecutive rows (:func:`alpha_grid`).
    q_fwd, q_bwd, distortion_fwd, distortion_bwd, lambda_*, texture_model, prior : passed to
        :func:`blend_costs` (only with an ImageMatrix).
    foreground_only : bool, average ``|div v|²`` over the union of the two silhouettes.

    Returns
    -------
    :class:`BlendPath`.

    Raises
    ------
    ValueError if ``ε < 1/(n_t − 1)`` or the grid admits no monotone path, or for
    inconsistent inputs.
    """
    if isinstance(matrix_or_costs, ImageMatrix):
        M = matrix_or_costs
        mask = _foreground(M.images) if foreground_only else None
        costs = blend_costs(M.alphas, n_t=len(M.t), Q=interpolation_quality(M.flows, mask),
                            q_fwd=q_fwd, q_bwd=q_bwd, distortion_fwd=distortion_fwd,
                            distortion_bwd=distortion_bwd, lambda_Q=lambda_Q,
                            lambda_dist=lambda_dist, lambda_mid=lambda_mid,
                            lambda_diag=lambda_diag, texture_model=texture_model, prior=prior)
    elif isinstance(matrix_or_costs, BlendCosts):
        costs = matrix_or_costs
        if any(x is not None for x in (q_fwd, q_bwd, distortion_fwd, distortion_bwd)):
            raise TypeError("q_*/distortion_* only apply to an ImageMatrix; fold them into the "
                            "BlendCosts with blend_costs(...)")
    else:
        raise TypeError(f"matrix_or_costs must be an ImageMatrix or BlendCosts, got "
                        f"{type(matrix_or_costs).__name__}")
    n_t, n_a = costs.vertex.shape
    al = costs.alphas
    if not (np.isfinite(eps) and eps > 0):
        raise ValueError(f"eps must be > 0, got {eps}")
    if (n_t - 1) * eps < 1 - _TOL:
        raise ValueError(f"eps = {eps:g} admits no path over {n_t} rows: α must climb from 0 to "
                         f"1 in {n_t - 1} steps, so eps ≥ 1/(n_t − 1) = {1 / (n_t - 1):.4g}; "
                         f"use alpha_grid({n_t}) or more rows")

    # ---- layered graph, vectorised over rows
    src, dst = _edges(al, eps)                                        # (E,)
    dal = al[dst] - al[src]                                           # (E,) ≥ 0
    w = costs.move[:, None] * dal[None, :] + costs.vertex[1:, dst]    # (n_t − 1, E)
    offset = max(np.abs(w).max(), 1e-12) - min(w.min(), 0.0)          # every weight ≥ max|w| > 0
    rows = np.arange(n_t - 1)[:, None] * n_a
    G = csr_matrix(((w + offset).ravel(), ((rows + src).ravel(), (rows + n_a + dst).ravel())),
                   shape=(n_t * n_a, n_t * n_a))
    source, target = 0, (n_t - 1) * n_a + (n_a - 1)
    dist, pred = dijkstra(G, directed=True, indices=source, return_predecessors=True)
    if not np.isfinite(dist[target]):
        raise ValueError(f"no monotone path from α = 0 to α = 1 with eps = {eps:g} on this "
                         f"α grid (spacing {np.diff(al).max():.4g}); use alpha_grid({n_t})")
    nodes = [target]
    while nodes[-1] != source:
        nodes.append(pred[nodes[-1]])
    nodes = np.array(nodes[::-1])
    if len(nodes) != n_t:                                             # layered graph: cannot fail
        raise RuntimeError("internal error: path does not visit one vertex per row")
    idx = (nodes % n_a).astype(np.int64)
    # re-priced exactly (dist[target] − (n_t − 1)·offset + vertex[0, 0] carries the offset's
    # rounding), so cost and diagonal_cost are comparable to the last bit
    return BlendPath(alphas=al[idx], indices=idx, cost=path_cost(costs, idx),
                     diagonal_cost=_diagonal_cost(costs))


def select_frames(matrix, path):
    """The frames of a path: ``matrix.images[i, path.indices[i]]``.

    Parameters
    ----------
    matrix : :class:`ImageMatrix`.
    path : :class:`BlendPath` (or (n_t,) int column indices).

    Returns
    -------
    (n_t, H, W, C) float32.
    """
    idx = np.asarray(path.indices if isinstance(path, BlendPath) else path)
    n_t, n_a = matrix.shape
    if idx.shape != (n_t,) or not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"path must have ({n_t},) integer indices, got {idx.dtype} {idx.shape}")
    if idx.min() < 0 or idx.max() >= n_a:
        raise ValueError(f"path indices must lie in [0, {n_a}), got [{idx.min()}, {idx.max()}]")
    return matrix.images[np.arange(n_t), idx]
