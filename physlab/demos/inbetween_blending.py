"""Lesson 08 (blending optimisation and evaluation): figures and the widget callback.

Brodt & Bessmeltsev 2024, Sec. 5 (5.1 texturing, 5.2 blending optimisation, Fig. 9, Table 1).
The algorithms live in :mod:`physlab.inbetween` (:mod:`~physlab.inbetween.pipeline`,
:mod:`~physlab.inbetween.blend`, :mod:`~physlab.inbetween.evaluate`); this module only
prepares a benchmark pair once and draws.

* :func:`prepared_pair` — one benchmark pair run through the pipeline (templates, deformation,
  ``I→(t)``, ``I←(t)``, flows, ``Q(t)``, distortions), its ground truth and its diagonal
  frames; cached (``functools.lru_cache``) so that a widget move only re-solves the path.
* :func:`choose_path` — costs → Dijkstra path → the path's frames → PSNR against the truth.
* :func:`blending_demo` — the widget callback (``params -> Figure``).
* :func:`sequences_figure`, :func:`flow_row_figure`, :func:`costs_figure` — static figures.
* :func:`side_by_side` — frames of several sequences next to each other, for an animation.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure

from physlab.inbetween import metrics
from physlab.inbetween.blend import (alpha_grid, blend_costs, blending_path, diagonal_path,
                                     render_path)
from physlab.inbetween.plots import draw_skeleton, over_white, plot_path
from physlab.viz.plots import new_figure

__all__ = ["PAIR_NAMES", "PreparedPair", "prepared_pair", "PathChoice", "choose_path",
           "blending_demo", "foreground_box", "sequences_figure", "flow_row_figure",
           "costs_figure", "side_by_side"]

#: names of :func:`physlab.inbetween.inbetween_benchmark` (6 tight, then 8 far)
PAIR_NAMES = ("nod", "wave_small", "lean", "step", "shrug", "bounce",
              "arm_swing", "wave_hello", "side_kick", "jumping_jack", "punch", "high_knee",
              "tumble", "disco")
BLENDS = ("optimal", "diagonal")
#: the pipeline's defaults for the cost terms not exposed in the widget
LAMBDA_DIST, PRIOR = 1.0, 0.01


# --------------------------------------------------------------------------- cached pipeline
@dataclass(frozen=True, eq=False)
class PreparedPair:
    """A benchmark pair after the expensive stages of the pipeline (read-only arrays).

    Attributes
    ----------
    pair : :class:`physlab.inbetween.characters.InbetweenPair`.
    keys : (2, H, W, 4) uint8, the keyframes.
    result : :class:`~physlab.inbetween.pipeline.InbetweenResult` (diagonal blend, no matrix):
        ``fwd``, ``bwd`` (n, H, W, 4) float32, ``Q`` (n,), ``distortion_fwd/bwd`` (n,), ...
    truth : (n, H, W, 4) uint8, the character rendered at every ``t`` (ground truth).
    diagonal_frames : (n, H, W, 4) float32, ``I(α = t, t)``.
    """

    pair: object
    keys: np.ndarray
    result: object
    truth: np.ndarray
    diagonal_frames: np.ndarray


def _check_int(value, name, lo, hi=None):
    if isinstance(value, bool) or int(value) != value:
        raise ValueError(f"{name} must be an integer, got {value!r}")
    v = int(value)
    if v < lo or (hi is not None and v > hi):
        rng = f"≥ {lo}" if hi is None else f"in [{lo}, {hi}]"
        raise ValueError(f"{name} must be {rng}, got {v}")
    return v


def prepared_pair(pair="arm_swing", size=192, n_frames=9):
    """The pipeline's expensive part for one benchmark pair, computed once per arguments.

    Parameters
    ----------
    pair : str, one of :data:`PAIR_NAMES`.
    size : int in [64, 512], image size in px.
    n_frames : int ≥ 3, frames including both keys.

    Returns
    -------
    :class:`PreparedPair` (cached: the same object for the same arguments; do not modify).
    """
    if pair not in PAIR_NAMES:
        raise ValueError(f"pair must be one of {PAIR_NAMES}, got {pair!r}")
    size = _check_int(size, "size", 64, 512)
    n_frames = _check_int(n_frames, "n_frames", 3, 41)
    return _prepared(pair, size, n_frames)


@functools.lru_cache(maxsize=4)
def _prepared(name, size, n_frames):
    from physlab.inbetween import inbetween_benchmark
    from physlab.inbetween import inbetween

    pair = {p.name: p for p in inbetween_benchmark(size)}[name]
    keys = np.stack(pair.keyframes())                                 # (2, H, W, 4) uint8
    res = inbetween(keys[0], keys[1], pair.skeleton0, pair.skeleton1, n_frames,
                    animation=pair.animation(n_frames), blend="diagonal")
    truth = np.asarray(pair.ground_truth(res.t))                      # (n, H, W, 4)
    diag = render_path(res.fwd, res.bwd, res.diagonal)                # (n, H, W, 4)
    for a in (keys, truth, diag, res.fwd, res.bwd):
        a.setflags(write=False)
    return PreparedPair(pair=pair, keys=keys, result=res, truth=truth, diagonal_frames=diag)


# --------------------------------------------------------------------------- the path
@dataclass(frozen=True, eq=False)
class PathChoice:
    """Output of :func:`choose_path`.

    Attributes
    ----------
    alphas : (n_α,) grid; eps : float, largest α step per frame.
    costs : BlendCosts; path, diagonal : BlendPath.
    frames : (n, H, W, 4) float32, the path's frames ``I(α_i, t_i)``.
    psnr_path, psnr_diagonal : (n − 2,) dB of the in-betweens against the ground truth.
    """

    alphas: np.ndarray
    eps: float
    costs: object
    path: object
    diagonal: object
    frames: np.ndarray
    psnr_path: np.ndarray
    psnr_diagonal: np.ndarray


def choose_path(prepared, speedup=3, lambda_Q=0.1, texture_model="variance", blend="optimal"):
    """Blending costs, the cheapest path and its frames for a :class:`PreparedPair`.

    Brodt & Bessmeltsev 2024, Sec. 5.2, with physlab's costs
    (:func:`~physlab.inbetween.blend.blend_costs`): ``ε = speedup/(n − 1)``
    (:func:`~physlab.inbetween.blend.alpha_grid`), Dijkstra
    (:func:`~physlab.inbetween.blend.blending_path`), frames by
    :func:`~physlab.inbetween.blend.render_path`.

    Parameters
    ----------
    prepared : :class:`PreparedPair`.
    speedup : int ≥ 1, how much faster than the diagonal α may move.
    lambda_Q : float ≥ 0, weight of the interpolation-quality edge term.
    texture_model : "variance" or "linear".
    blend : "optimal" (Dijkstra) or "diagonal" (α = t).

    Returns
    -------
    :class:`PathChoice`.
    """
    if blend not in BLENDS:
        raise ValueError(f"blend must be one of {BLENDS}, got {blend!r}")
    res = prepared.result
    n = len(res.t)
    alphas, eps = alpha_grid(n, speedup=speedup)
    costs = blend_costs(alphas, n_t=n, Q=res.Q, distortion_fwd=res.distortion_fwd,
                        distortion_bwd=res.distortion_bwd, lambda_Q=lambda_Q,
                        lambda_dist=LAMBDA_DIST, texture_model=texture_model, prior=PRIOR)
    diagonal = diagonal_path(n, alphas, costs)
    path = blending_path(costs, eps) if blend == "optimal" else diagonal
    frames = render_path(res.fwd, res.bwd, path)                      # (n, H, W, 4)
    frames[0], frames[-1] = prepared.keys[0] / 255.0, prepared.keys[1] / 255.0

    def score(seq):
        return np.array([metrics.psnr(f, g) for f, g in zip(seq[1:-1], prepared.truth[1:-1])])

    return PathChoice(alphas=alphas, eps=eps, costs=costs, path=path, diagonal=diagonal,
                      frames=frames, psnr_path=score(frames),
                      psnr_diagonal=score(prepared.diagonal_frames))


def blending_demo(speedup=3, lambda_Q=0.1, texture_model="variance", blend="optimal",
                  pair="arm_swing", size=192, n_frames=9):
    """Widget callback: the blending path for one setting, its frames and their PSNR.

    Top left: vertex costs (colour), the chosen path (green) and the diagonal (red).
    Top right: PSNR of every in-between against the ground truth, path and diagonal.
    Bottom: the chosen frames, labelled with α and PSNR.
    The pipeline's expensive part is cached (:func:`prepared_pair`); a call costs the path and
    ``n_frames`` interpolations (≈ 0.2 s at 192 px).
    """
    prep = prepared_pair(pair, size, n_frames)
    c = choose_path(prep, speedup=speedup, lambda_Q=lambda_Q, texture_model=texture_model,
                    blend=blend)
    n = len(prep.result.t)
    fig = Figure(figsize=(max(7.0, 0.95 * n), 4.9), layout="constrained")
    top, bottom = fig.subfigures(2, 1, height_ratios=[1.75, 1.0])
    ax_path, ax_psnr = top.subplots(1, 2, width_ratios=[1.25, 1.0])
    im = plot_path(ax_path, c.costs, c.path, c.diagonal)
    ax_path.lines[-1].set_label(f"chosen path ({blend})")          # plot_path draws it last
    ax_path.legend(loc="upper right", fontsize=7)
    top.colorbar(im, ax=ax_path, label="vertex cost Δt·c(α, t)", shrink=0.9)
    ax_path.set_title(f"ε = {c.eps:.3g} (speedup {speedup}), λ_Q = {lambda_Q:g}, "
                      f"{texture_model}", fontsize=8)
    rows = np.arange(1, n - 1)
    ax_psnr.plot(rows, c.psnr_diagonal, "o--", color="tab:red", ms=4, label="diagonal α = t")
    ax_psnr.plot(rows, c.psnr_path, "o-", color="tab:green", ms=4, label=f"chosen path ({blend})")
    ax_psnr.set_xlabel("frame")
    ax_psnr.set_ylabel("PSNR vs ground truth (dB)")
    ax_psnr.set_title(f"mean PSNR {c.psnr_path.mean():.2f} dB (diagonal "
                      f"{c.psnr_diagonal.mean():.2f} dB)\npath cost {c.path.cost:.4f} "
                      f"(diagonal {c.diagonal.cost:.4f})", fontsize=8)
    ax_psnr.legend(fontsize=7)
    ax_psnr.grid(alpha=0.3)
    box = foreground_box(prep.result.fwd, prep.result.bwd, prep.truth)
    for i, ax in enumerate(bottom.subplots(1, n)):
        lab = "key" if i in (0, n - 1) else f"{c.psnr_path[i - 1]:.1f} dB"
        _show(ax, c.frames[i], box, f"α={c.path.alphas[i]:.2f}\n{lab}")
    bottom.suptitle(f"{pair}: the frames of the {blend} path", fontsize=8)
    return fig


# --------------------------------------------------------------------------- static figures
def foreground_box(*stacks, margin=6):
    """Slices ``(rows, cols)`` of the box around every non-white / non-transparent pixel.

    Parameters
    ----------
    stacks : arrays (..., H, W, 3|4), uint8 or float in [0, 1] (RGBA: alpha > 0.05 is
        foreground; RGB: any channel below 0.95).
    margin : int px added on every side (clipped to the image).

    Returns
    -------
    (slice, slice), to crop the figures to the character: ``images[..., rows, cols, :]``.
    """
    if not stacks:
        raise ValueError("foreground_box needs at least one image stack")
    H, W = np.asarray(stacks[0]).shape[-3:-1]
    fg = np.zeros((H, W), bool)
    for s in stacks:
        s = np.asarray(s)
        s = s.astype(np.float32) / 255.0 if s.dtype == np.uint8 else s
        if s.shape[-3:-1] != (H, W):
            raise ValueError(f"all stacks must have the same image size, got {s.shape}")
        m = s[..., 3] > 0.05 if s.shape[-1] == 4 else (s[..., :3] < 0.95).any(-1)
        fg |= m.reshape(-1, H, W).any(0)
    if not fg.any():
        return slice(0, H), slice(0, W)
    ys, xs = np.flatnonzero(fg.any(1)), np.flatnonzero(fg.any(0))
    return (slice(max(ys[0] - margin, 0), min(ys[-1] + margin + 1, H)),
            slice(max(xs[0] - margin, 0), min(xs[-1] + margin + 1, W)))


def _show(ax, img, box, label=None):
    """imshow the ``box`` crop of ``img`` in full-image pixel coordinates (ticks off)."""
    rows, cols = box
    ax.imshow(over_white(img[rows, cols]),
              extent=(cols.start - 0.5, cols.stop - 0.5, rows.stop - 0.5, rows.start - 0.5))
    ax.set_xlim(cols.start - 0.5, cols.stop - 0.5)
    ax.set_ylim(rows.stop - 0.5, rows.start - 0.5)
    ax.set_xticks([])
    ax.set_yticks([])
    if label is not None:
        ax.set_xlabel(label, fontsize=7)


def sequences_figure(result, width=0.8):
    """The two deformed sequences (Sec. 5.1): ``I→(t)`` (top) and ``I←(t)`` (bottom), cropped
    to the character, with the skeleton ``x_i(t)`` both follow (thin red).

    Parameters
    ----------
    result : InbetweenResult (``fwd``, ``bwd``, ``skeletons``, ``t``).
    width : float, inches per frame.
    """
    n = len(result.t)
    box = foreground_box(result.fwd, result.bwd)
    h, w = box[0].stop - box[0].start, box[1].stop - box[1].start
    fig, axes = new_figure(ncols=n, nrows=2, width=width, height=width * h / w + 0.12)
    axes = np.asarray(axes).reshape(2, n)
    for r, (seq, name) in enumerate(((result.fwd, "I→(t)\nkey 0's texture"),
                                     (result.bwd, "I←(t)\nkey 1's texture"))):
        for i in range(n):
            ax = axes[r, i]
            _show(ax, seq[i], box, f"t={result.t[i]:.2f}" if r == 1 else None)
            draw_skeleton(ax, result.skeletons[i], color=(0.85, 0.1, 0.1, 0.45), lw=0.6, ms=0.8)
            if i == 0:
                ax.set_ylabel(name, fontsize=7)
    return fig


def _divergence(v):
    """(H, W, 2) flow -> (H, W) ``∂v_x/∂x + ∂v_y/∂y`` (central differences)."""
    return np.gradient(v[..., 0], axis=1) + np.gradient(v[..., 1], axis=0)


def flow_row_figure(result, row, alphas=(0.0, 0.25, 0.5, 0.75, 1.0), interpolator=None,
                    step=5):
    """One row of the image matrix: ``I→(t)``, ``I←(t)``, the flow ``v(t)`` between them, its
    divergence, and the interpolated frames ``F(I→(t), I←(t), α)`` (cropped to the character).

    Parameters
    ----------
    result : InbetweenResult.
    row : int, the frame index ``i`` (``t = result.t[i]``).
    alphas : α values of the bottom row.
    interpolator : FrameInterpolator, default ``FlowInterpolator()``.
    step : int, quiver spacing in px.
    """
    from physlab.inbetween.frame_interpolation import FlowInterpolator

    n = len(result.t)
    row = _check_int(row, "row", 0, n - 1)
    interp = FlowInterpolator() if interpolator is None else interpolator
    a, b = result.fwd[row], result.bwd[row]
    v = interp.flow(a, b)                                            # (H, W, 2) px
    fg = (a[..., 3] > 0.5) | (b[..., 3] > 0.5)
    frames = interp(a, b, np.asarray(alphas, dtype=float))           # (k, H, W, 4)
    box = foreground_box(a, b)
    rows, cols = box
    fig = Figure(figsize=(7.6, 4.4), layout="constrained")
    top, bottom = fig.subfigures(2, 1, height_ratios=[1.15, 1.0])
    ax = top.subplots(1, 4)
    _show(ax[0], a, box)
    ax[0].set_title(f"I→(t = {result.t[row]:.2f})", fontsize=8)
    _show(ax[1], b, box)
    ax[1].set_title("I←(t)", fontsize=8)
    ext = (cols.start - 0.5, cols.stop - 0.5, rows.stop - 0.5, rows.start - 0.5)
    mag = np.where(fg, np.hypot(v[..., 0], v[..., 1]), np.nan)
    im = ax[2].imshow(mag[rows, cols], cmap="magma_r", extent=ext, vmin=0)
    top.colorbar(im, ax=ax[2], shrink=0.8, label="|v| (px)")
    y, x = np.mgrid[rows.start + step // 2:rows.stop:step, cols.start + step // 2:cols.stop:step]
    keep = fg[y, x] & (np.hypot(v[y, x, 0], v[y, x, 1]) > 0.5)
    ax[2].quiver(x[keep], y[keep], v[y, x, 0][keep], v[y, x, 1][keep], angles="xy",
                 scale_units="xy", scale=0.5, width=0.01, color="tab:blue")
    ax[2].set_title("flow v(t), I→ → I← (arrows ×2)", fontsize=8)
    div = np.where(fg, _divergence(v), np.nan)
    lim = max(np.nanmax(np.abs(div)), 1e-6)
    im = ax[3].imshow(div[rows, cols], cmap="RdBu_r", vmin=-lim, vmax=lim, extent=ext)
    top.colorbar(im, ax=ax[3], shrink=0.8, label="div v")
    ax[3].set_title(f"Q(t) = mean |div v|² = {result.Q[row]:.3g}", fontsize=8)
    for axi in ax[2:]:
        axi.set_xlim(ext[:2])
        axi.set_ylim(ext[2:])
        axi.set_xticks([])
        axi.set_yticks([])
    axb = np.atleast_1d(bottom.subplots(1, len(alphas)))
    for k, axi in enumerate(axb):
        _show(axi, frames[k], box, f"α = {alphas[k]:.2f}")
    bottom.suptitle("the row I(α, t) = F(I→(t), I←(t), α): DIS optical flow + warping "
                    "(physlab's stand-in for RIFE)", fontsize=8)
    return fig


def costs_figure(result, prior=PRIOR):
    """The blending costs of a pipeline result (Sec. 5.2, physlab's variance model).

    Left: vertex costs, the optimal path (green), the diagonal (red) and the texture term's
    row minimiser ``α*(t) = σ→²/(σ→² + σ←²)`` (white dots). Right: the per-row inputs
    ``D→(t)``, ``D←(t)`` (symmetric-Dirichlet distortion ``E_d/4 − 1``) and ``Q(t)``.
    """
    t = result.t
    v_fwd = result.distortion_fwd + prior * t                         # σ→²
    v_bwd = result.distortion_bwd + prior * (1.0 - t)                 # σ←²
    a_star = v_fwd / (v_fwd + v_bwd)
    fig, (ax0, ax1) = new_figure(ncols=2, width=3.6, height=3.0)
    im = plot_path(ax0, result.costs, result.path, result.diagonal)
    rows = np.arange(len(t))
    ax0.plot(a_star, rows, ":", marker="s", color="white", ms=3, lw=1,
             label="α* = σ→²/(σ→²+σ←²)")
    ax0.legend(loc="upper right", fontsize=6)
    fig.colorbar(im, ax=ax0, shrink=0.8, label="Δt·c(α, t)")
    ax0.set_title(f"vertex costs, ε = {result.eps:.3g}", fontsize=8)
    ax1.plot(t, result.distortion_fwd, "o-", ms=3, label="D→(t) (key 0's texture)")
    ax1.plot(t, result.distortion_bwd, "s-", ms=3, label="D←(t) (key 1's texture)")
    ax1.plot(t, result.Q, "^-", ms=3, color="0.3", label="Q(t) = mean |div v|²")
    ax1.set_xlabel("t")
    ax1.set_ylabel("dimensionless")
    ax1.set_title("per-row cost inputs", fontsize=8)
    ax1.legend(fontsize=6)
    ax1.grid(alpha=0.3)
    return fig


def side_by_side(*sequences, gap=4):
    """(n, H, W·k + gap·(k − 1), 3) uint8: the k sequences composited over white, next to
    each other (for :func:`physlab.render.frames_to_html`)."""
    if not sequences:
        raise ValueError("side_by_side needs at least one sequence")
    seqs = [np.asarray(s) for s in sequences]
    n, H = len(seqs[0]), seqs[0].shape[1]
    if any(len(s) != n or s.shape[1] != H for s in seqs):
        raise ValueError(f"sequences must have the same length and height, got "
                         f"{[s.shape for s in seqs]}")
    white = np.ones((n, H, gap, 3), np.float32)
    parts = []
    for s in seqs:
        s = s.astype(np.float32) / 255.0 if s.dtype == np.uint8 else s.astype(np.float32)
        parts += [over_white(s), white]
    out = np.concatenate(parts[:-1], axis=2)
    return (np.clip(out, 0, 1) * 255 + 0.5).astype(np.uint8)
