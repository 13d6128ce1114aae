"""The inbetweening pipeline: two keyframes + skeletons → in-between frames.

Brodt & Bessmeltsev 2024, Secs. 4–5, for drawings without occlusions:

1. a template per keyframe (:func:`~physlab.inbetween.template.build_template`, Secs. 4.1–4.2);
2. the skeletal animation ``x_i(t)``: given, or :func:`~physlab.inbetween.skeleton.interpolate`
   (bone angles and lengths) between the key skeletons;
3. both templates deformed into every pose (Sec. 4.3, Eq. 1) — template 0 forwards from
   t = 0, template 1 backwards from t = 1, each frame warm-started from the previous one —
   and textured with their keyframe (Sec. 5.1), giving ``I→(t)`` and ``I←(t)``;
4. the blending optimisation (Sec. 5.2): flows between ``I→(t)`` and ``I←(t)``, costs, the
   cheapest path through the image matrix ``I(α, t)``, and its frames
   (:mod:`physlab.inbetween.blend`; RIFE replaced by :class:`FlowInterpolator`).

With occlusions (layered templates, :mod:`physlab.inbetween.occlusion`) step 3 also draws each
template's inpainted-texel mask into every pose (the visible pixels whose texture was inpainted,
:meth:`~physlab.inbetween.occlusion.LayeredTemplate.render_inpainted`), and step 4 turns them
into the texture qualities ``q_0(t) = q(I→(t))``, ``q_1(t) = q(I←(t))``
(:func:`~physlab.inbetween.blend.texture_quality`, Sec. 5.2) of the vertex cost: the blend leans
on the key whose texture is less inpainted at that frame. Without occlusions nothing is
inpainted, ``q ≡ 1``, and the costs are those of the no-occlusion case.
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from .blend import (alpha_grid, blend_costs, blending_path, diagonal_path, image_matrix,
                    interpolation_quality, render_path, row_flows)
from .blend import texture_quality as texture_quality_of
from .deform import (MAX_HANDLE_STEP, MAX_ITER, MU, TOL, SymmetricDirichletDeformer,
                     deform_through, flipped_count, substeps)
from .frame_interpolation import FlowInterpolator
from .occlusion import build_layered_template, limb_overlaps
from .skeleton import Skeleton, check_compatible, interpolate
from .template import as_rgba_float, build_template

__all__ = ["inbetween", "InbetweenResult", "deform_sequence", "substeps", "DEFORMERS", "BLENDS",
           "TEXTURE_QUALITIES"]

DEFORMERS = ("symmetric_dirichlet", "arap", "lbs")
DISTORTION_CAP = 100.0  #: texture distortion assigned to frames with folded triangles
BLENDS = ("optimal", "diagonal")
#: ``inbetween(texture_quality=)``: q from the inpainted masks (Sec. 5.2), or q ≡ 1 (ablation)
TEXTURE_QUALITIES = ("inpainted", "none")
HANDLE_FLAG_PX = 2.0  #: frames whose largest handle error exceeds this (px) are flagged


@dataclass
class InbetweenResult:
    """Frames and intermediate products of :func:`inbetween`.

    Attributes
    ----------
    frames : (n, H, W, C) float32 in [0, 1]: key 0, the in-betweens, key 1 (C = 4 for RGBA
        keys, 3 for opaque keys, composited over the paper colour).
    t : (n,) times ``linspace(0, 1, n)``.
    skeletons : list of n Skeletons, the skeletal animation used.
    templates : (Template, Template) of key 0 and key 1.
    x_fwd, x_bwd : (n, n0, 2), (n, n1, 2) deformed template vertices per frame (pixels).
    fwd, bwd : (n, H, W, 4) float32 straight RGBA, ``I→(t)`` and ``I←(t)``.
    distortion_fwd, distortion_bwd : (n,) texture distortion ``E_d/4 − 1`` per frame.
    handle_error : (2, n) largest handle error (px) per template and frame.
    flipped : (2, n) flipped-triangle count per template and frame.
    alphas, eps : the α grid and the largest α step per frame.
    Q : (n,) interpolation quality per row (mean ``|div v|²`` over the foreground).
    path : BlendPath (chosen), diagonal : BlendPath (α = t, same costs).
    costs : BlendCosts.
    matrix : ImageMatrix or None (``keep_matrix=True``).
    timings : dict stage → seconds.
    flags : list of n tuples of str, per-frame quality flags: ``"overlap:a/b"`` (bones into
        joints a and b overlap in 2D and no occlusion information covers them),
        ``"handle_error"`` (a handle ended more than 2 px from its target), ``"flipped"``
        (folded triangles). Empty tuples for clean frames.
    q_fwd, q_bwd : (n,) float64 in [0, 1], per-frame texture quality of ``I→(t)`` and
        ``I←(t)`` (Sec. 5.2): ``1 − |A ∩ F| / |F|`` with ``A`` the visible inpainted pixels
        and ``F`` the frame's silhouette (alpha > 0.5). All ones without occlusions. Measured in
        both ``texture_quality`` modes; they enter ``costs`` only with ``"inpainted"``.
    inpainted_fwd, inpainted_bwd : (n, H, W) bool, the visible inpainted pixels ``A`` of each
        frame (layered templates), or None (single sheets: nothing is inpainted).
    """

    frames: np.ndarray
    t: np.ndarray
    skeletons: list
    templates: tuple
    x_fwd: np.ndarray
    x_bwd: np.ndarray
    fwd: np.ndarray
    bwd: np.ndarray
    distortion_fwd: np.ndarray
    distortion_bwd: np.ndarray
    handle_error: np.ndarray
    flipped: np.ndarray
    alphas: np.ndarray
    eps: float
    Q: np.ndarray
    path: object
    diagonal: object
    costs: object
    matrix: object = None
    timings: dict = field(default_factory=dict)
    flags: list = field(default_factory=list)
    q_fwd: np.ndarray = None
    q_bwd: np.ndarray = None
    inpainted_fwd: np.ndarray = None
    inpainted_bwd: np.ndarray = None

    def __repr__(self):
        n, H, W, C = self.frames.shape
        return (f"InbetweenResult({n} frames {W}x{H}x{C}, path α={np.round(self.path.alphas, 2)}, "
                f"max handle error {self.handle_error.max():.2g} px, "
                f"flipped {int(self.flipped.sum())})")


def _progress(it, progress, desc):
    if not progress:
        return it
    from tqdm.auto import tqdm

    return tqdm(it, desc=desc, leave=False)


def deform_sequence(template, skeletons, deformer="symmetric_dirichlet", order=None,
                    progress=False, max_handle_step=MAX_HANDLE_STEP, **options):
    """Deform a template into every skeleton of a sequence, warm-starting each frame.

    Parameters
    ----------
    template : Template.
    skeletons : list of n Skeletons with the template's topology.
    deformer : "symmetric_dirichlet" (Eq. 1, default), "arap" or "lbs" (comparisons,
        :mod:`physlab.inbetween.skinning`).
    order : iterable of frame indices in solving order (default 0..n−1; the backward
        template uses n−1..0 so it starts from its own keyframe).
    max_handle_step : float px; when a handle moves more than this between two frames (or
        from the template's own pose to the first frame solved), the symmetric Dirichlet
        solve goes through intermediate poses (:func:`interpolate`), each warm-started from
        the last: large rotations reached in one solve can get stuck in distorted local
        minima, as the pose term (μ = 200 per px²) pulls handles far ahead of the mesh.
    options : ``mu``, ``tol``, ``max_iter``, ``method`` ("lbfgs" or "gradient") for the
        symmetric Dirichlet deformer.

    Returns
    -------
    x : (n, n_vertices, 2) positions (pixels); energy_d : (n,) ``E_d`` per frame;
    handle_error : (n,) largest handle error (px); flipped : (n,) flipped-triangle counts.
    """
    from .deform import symmetric_dirichlet_energy

    if deformer not in DEFORMERS:
        raise ValueError(f"deformer must be one of {DEFORMERS}, got {deformer!r}")
    n = len(skeletons)
    order = list(range(n)) if order is None else list(order)
    targets = [template.targets(s) for s in skeletons]  # also checks the topology
    X, tris = template.X, template.tris
    xs = np.empty((n, len(X), 2))
    if deformer == "symmetric_dirichlet":
        D = SymmetricDirichletDeformer(template, mu=options.get("mu", MU))
        solve = dict(tol=options.get("tol", TOL), max_iter=options.get("max_iter", MAX_ITER),
                     method=options.get("method", "lbfgs"))
        x, prev = None, template.skeleton
        for i in _progress(order, progress, "deform"):
            x = deform_through(D, [skeletons[i]], x0=x, start=prev,
                               max_handle_step=max_handle_step, **solve).x
            xs[i], prev = x, skeletons[i]
    else:
        from .skinning import bbw_weights, skeleton_deform

        weights = bbw_weights(X, tris, template.skeleton, template.handle_vertices)
        for i in _progress(order, progress, "deform"):
            xs[i] = skeleton_deform(X, tris, template.skeleton, skeletons[i],
                                    template.handle_vertices, method=deformer, weights=weights)
    energy = np.array([symmetric_dirichlet_energy(X, tris, x) for x in xs])
    err = np.array([np.linalg.norm(template.handle_positions(x) - tg, axis=1).max()
                    for x, tg in zip(xs, targets)])
    flipped = np.array([flipped_count(X, x, tris) for x in xs])
    return xs, energy, err, flipped


def _paper_colour(img, mask):
    """Median RGB of the background (non-mask) pixels of an opaque keyframe."""
    bg = img[..., :3][~mask]
    return np.median(bg, axis=0) if len(bg) else np.ones(3, np.float32)


#: Largest ``n_frames`` :func:`inbetween` accepts, and the largest memory for its frames.
MAX_FRAMES = 1000
MAX_BYTES = 4 * 2**30


def inbetween(key0, key1, skeleton0, skeleton1, n_frames, animation=None, *, mask0=None,
              mask1=None, mask_predictor=None, max_area=None, deformer="symmetric_dirichlet",
              mu=MU, tol=TOL, max_iter=MAX_ITER, solver="lbfgs", interpolator=None,
              blend="optimal",
              speedup=3, texture_model="variance", lambda_Q=0.1, lambda_dist=1.0,
              lambda_mid=0.0, prior=0.01, keep_matrix=False, progress=False,
              occlusions0=None, occlusions1=None, strict=False, texture_quality="inpainted"):
    """In-between frames of two keyframe drawings driven by a skeletal animation.

    Brodt & Bessmeltsev 2024, Secs. 4–5 (module docstring for the stages).

    Parameters
    ----------
    key0, key1 : (H, W, 3|4) uint8 or float images of the same size.
    skeleton0, skeleton1 : Skeletons of the keys (pixels), same topology.
    n_frames : int ≥ 2, frames including both keys (9 in-betweens → 11).
    animation : None (interpolate bone angles and lengths) or a list of ``n_frames``
        Skeletons, the skeletal motion ``x_i(t)`` (the first and last should match the keys).
    mask0, mask1 : foreground masks, or None to predict them (``mask_predictor``, default
        the classical mask of :mod:`physlab.inbetween.template`).
    max_area : Triangle's max triangle area (px²), None for the default (a few hundred).
    deformer : "symmetric_dirichlet" (paper), "arap" or "lbs" (comparisons).
    mu, tol, max_iter : symmetric Dirichlet options (paper: 200, 0.01, 5000).
    solver : "lbfgs" (Laplacian-preconditioned quasi-Newton, default) or "gradient" (the
        plain Sobolev gradient method).
    interpolator : FrameInterpolator (default ``FlowInterpolator()``, the RIFE stand-in).
    blend : "optimal" (the blending optimisation) or "diagonal" (α = t).
    speedup : ε = speedup/(n_frames − 1), see :func:`~physlab.inbetween.blend.alpha_grid`.
    texture_model, lambda_Q, lambda_dist, lambda_mid, prior : blending costs
        (:func:`~physlab.inbetween.blend.blend_costs`); defaults: the variance model with
        λ_Q = 0.1 and prior 0.01, chosen on a validation variant of the benchmark (other seeds
        and styles) among λ_Q ∈ {0, 0.1, 1}, prior ∈ {1e-3, 1e-2}.
    keep_matrix : bool, also compute the whole image matrix (n·n_α frames; lessons, small
        images only).
    progress : bool, tqdm bars.
    occlusions0, occlusions1 : None, or lists of :class:`~physlab.inbetween.occlusion.Occlusion`
        of each key (an empty list: the key has none). When either is given, both templates
        are :func:`~physlab.inbetween.occlusion.build_layered_template` s (Secs. 4.1–4.4,
        5.1): occlusion layers whose topology is chosen by deforming towards the other key,
        triangles drawn back to front by the skeleton's joint depths, back layers textured
        from the other key or inpainted.
    strict : bool. Without occlusion information, a skeletal motion that makes non-adjacent
        bones overlap in 2D (:func:`~physlab.inbetween.occlusion.limb_overlaps`) warns naming
        the joints (a single sheet tears there); ``strict=True`` raises instead.
    texture_quality : "inpainted" (default): the vertex cost uses the texture qualities
        ``q_0(t)``, ``q_1(t)`` of the two deformed sequences, measured from the visible
        inpainted pixels of the layered templates (Sec. 5.2); "none": ``q ≡ 1`` (the blend
        ignores inpainting — an ablation). No effect without occlusions (nothing is inpainted).

    Returns
    -------
    InbetweenResult.

    Raises
    ------
    ValueError for keys of different sizes, skeletons of different topology, joints outside
    the image, empty masks, a bad ``n_frames`` / ``animation`` / option.
    """
    timings = {}
    tic = time.perf_counter()
    k0, k1 = as_rgba_float(key0, "key0"), as_rgba_float(key1, "key1")
    if k0.shape != k1.shape:
        raise ValueError(f"key0 and key1 must have the same size, got {k0.shape[:2]} and "
                         f"{k1.shape[:2]} (resize or pad one of them)")
    check_compatible(skeleton0, skeleton1)
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer, float)) \
            or not np.isfinite(n_frames) or int(n_frames) != n_frames or n_frames < 2:
        raise ValueError(f"n_frames must be an integer ≥ 2 (both keys included), got "
                         f"{n_frames!r}")
    n = int(n_frames)
    # The two deformed sequences and the blended frames hold ~3 float32 RGBA images a frame.
    need = 3 * n * k0.shape[0] * k0.shape[1] * 4 * 4
    if n > MAX_FRAMES or need > MAX_BYTES:
        raise ValueError(f"n_frames = {n} is too many for {k0.shape[1]}x{k0.shape[0]} keys: "
                         f"the limit is {MAX_FRAMES} frames and {MAX_BYTES / 2**30:.0f} GiB of "
                         f"frames (this needs {need / 2**30:.1f} GiB); ask for fewer frames or "
                         f"smaller images")
    if blend not in BLENDS:
        raise ValueError(f"blend must be one of {BLENDS}, got {blend!r}")
    if texture_quality not in TEXTURE_QUALITIES:
        raise ValueError(f"texture_quality must be one of {TEXTURE_QUALITIES}, got "
                         f"{texture_quality!r}")
    t = np.linspace(0.0, 1.0, n)
    if animation is None:
        skeletons = interpolate(skeleton0, skeleton1, t)
    else:
        skeletons = list(animation)
        if len(skeletons) != n:
            raise ValueError(f"animation has {len(skeletons)} skeletons, expected n_frames = {n}")
        for i, s in enumerate(skeletons):
            if not isinstance(s, Skeleton):
                raise TypeError(f"animation[{i}] is not a Skeleton")
            check_compatible(skeleton0, s, ("skeleton0", f"animation[{i}]"))
    opaque = bool(k0[..., 3].min() == 1.0 and k1[..., 3].min() == 1.0)
    layered = occlusions0 is not None or occlusions1 is not None
    overlaps = [() if layered else tuple(f"overlap:{a}/{b}" for a, b in limb_overlaps(s))
                for s in skeletons]
    if any(overlaps):
        bad = sorted({f for fl in overlaps for f in fl})
        frames_hit = [i for i, fl in enumerate(overlaps) if fl]
        msg = (f"the skeletal motion makes limbs overlap ({', '.join(b[8:] for b in bad)} in "
               f"frames {frames_hit}) but no occlusion information was given: a single-layer "
               "template tears there. Pass occlusions0/occlusions1 (physlab.inbetween."
               "suggest_occlusions or character_occlusions give a start) and joint depths")
        if strict:
            raise ValueError(msg)
        warnings.warn(msg, stacklevel=2)

    if layered:
        def towards(seq):  # poses the template is scored on (Sec. 4.3): ≤ 4, the far key last
            idx = np.unique(np.linspace(1, len(seq) - 1, min(4, len(seq) - 1)).round().astype(int))
            return [seq[i] for i in idx]

        tpl0 = build_layered_template(
            k0, skeleton0, occlusions0 or (), mask=mask0, mask_predictor=mask_predictor,
            max_area=max_area, target_skeletons=towards(skeletons), other_image=k1,
            other_occlusions=occlusions1 or (), other_mask=mask1, mu=mu, name="key0")
        tpl1 = build_layered_template(
            k1, skeleton1, occlusions1 or (), mask=mask1, mask_predictor=mask_predictor,
            max_area=max_area, target_skeletons=towards(skeletons[::-1]), other_image=k0,
            other_occlusions=occlusions0 or (), other_mask=mask0, mu=mu, name="key1")
    else:
        tpl0 = build_template(k0, skeleton0, mask=mask0, mask_predictor=mask_predictor,
                              max_area=max_area, name="key0")
        tpl1 = build_template(k1, skeleton1, mask=mask1, mask_predictor=mask_predictor,
                              max_area=max_area, name="key1")
    timings["template"] = time.perf_counter() - tic

    tic = time.perf_counter()
    opts = dict(mu=mu, tol=tol, max_iter=max_iter, method=solver)
    x0s, e0, err0, flip0 = deform_sequence(tpl0, skeletons, deformer, progress=progress, **opts)
    x1s, e1, err1, flip1 = deform_sequence(tpl1, skeletons, deformer, order=range(n - 1, -1, -1),
                                           progress=progress, **opts)
    timings["deform"] = time.perf_counter() - tic

    tic = time.perf_counter()
    H, W = k0.shape[:2]
    inp0 = inp1 = None
    if layered:  # triangles back to front at each frame's joint depths
        fwd = np.stack([tpl0.render(x, (H, W), skeleton=s)
                        for x, s in _progress(list(zip(x0s, skeletons)), progress, "render I→")])
        bwd = np.stack([tpl1.render(x, (H, W), skeleton=s)
                        for x, s in _progress(list(zip(x1s, skeletons)), progress, "render I←")])
        # the inpainted texels drawn like the texture: visible inpainted pixels (Sec. 5.2)
        inp0 = np.stack([tpl0.render_inpainted(x, (H, W), skeleton=s)
                         for x, s in zip(x0s, skeletons)])                 # (n, H, W) bool
        inp1 = np.stack([tpl1.render_inpainted(x, (H, W), skeleton=s)
                         for x, s in zip(x1s, skeletons)])
    else:
        fwd = np.stack([tpl0.render(x, (H, W)) for x in _progress(x0s, progress, "render I→")])
        bwd = np.stack([tpl1.render(x, (H, W)) for x in _progress(x1s, progress, "render I←")])
    timings["render"] = time.perf_counter() - tic

    tic = time.perf_counter()
    interp = FlowInterpolator() if interpolator is None else interpolator
    alphas, eps = alpha_grid(n, speedup=speedup)
    matrix = None
    if keep_matrix:
        matrix = image_matrix(fwd, bwd, alphas, interp, progress=progress)
        flows = matrix.flows
    else:
        flows = row_flows(fwd, bwd, interp, progress=progress)
    fg = (fwd[..., 3] > 0.5) | (bwd[..., 3] > 0.5)
    Q = np.array([interpolation_quality(f, m) for f, m in zip(flows, fg)])
    # distortion D = E_d/4 − 1 (0 = rigid); frames with folded triangles (LBS/ARAP only) have
    # E_d = ∞ and get the cap DISTORTION_CAP
    dist0 = np.clip(np.nan_to_num(e0 / 4.0 - 1.0, posinf=DISTORTION_CAP), 0.0, DISTORTION_CAP)
    dist1 = np.clip(np.nan_to_num(e1 / 4.0 - 1.0, posinf=DISTORTION_CAP), 0.0, DISTORTION_CAP)
    # texture quality q = 1 − |A ∩ F| / |F| of each deformed sequence (Sec. 5.2); all ones
    # without layered templates (inp = None)
    q0 = texture_quality_of(inp0, None if inp0 is None else fwd[..., 3] > 0.5, n_t=n)
    q1 = texture_quality_of(inp1, None if inp1 is None else bwd[..., 3] > 0.5, n_t=n)
    use_q = texture_quality == "inpainted"
    costs = blend_costs(alphas, n_t=n, Q=Q, q_fwd=q0 if use_q else None,
                        q_bwd=q1 if use_q else None, distortion_fwd=dist0,
                        distortion_bwd=dist1, lambda_Q=lambda_Q, lambda_dist=lambda_dist,
                        lambda_mid=lambda_mid, texture_model=texture_model, prior=prior)
    diagonal = diagonal_path(n, alphas, costs)
    path = blending_path(costs, eps) if blend == "optimal" else diagonal
    timings["flow+path"] = time.perf_counter() - tic

    tic = time.perf_counter()
    if matrix is not None:
        frames = matrix.images[np.arange(n), path.indices]
    else:
        frames = render_path(fwd, bwd, path, interp)
    frames = np.asarray(frames, np.float32).copy()
    frames[0], frames[-1] = k0, k1  # the keys exactly (outside-mask pixels included)
    if opaque:  # paper drawings: composite the in-betweens over the paper colour
        paper = 0.5 * (_paper_colour(k0, tpl0.mask) + _paper_colour(k1, tpl1.mask))
        a = frames[..., 3:4]
        frames = (frames[..., :3] * a + paper * (1.0 - a)).astype(np.float32)
    timings["blend"] = time.perf_counter() - tic
    flags = []
    for i in range(n):
        f = list(overlaps[i])
        if max(err0[i], err1[i]) > HANDLE_FLAG_PX:
            f.append("handle_error")
        if flip0[i] or flip1[i]:
            f.append("flipped")
        flags.append(tuple(f))
    return InbetweenResult(
        frames=frames, t=t, skeletons=skeletons, templates=(tpl0, tpl1), x_fwd=x0s, x_bwd=x1s,
        fwd=fwd, bwd=bwd, distortion_fwd=dist0, distortion_bwd=dist1,
        handle_error=np.stack([err0, err1]), flipped=np.stack([flip0, flip1]), alphas=alphas,
        eps=eps, Q=Q, path=path, diagonal=diagonal, costs=costs, matrix=matrix, timings=timings,
        flags=flags, q_fwd=q0, q_bwd=q1, inpainted_fwd=inp0, inpainted_bwd=inp1)
