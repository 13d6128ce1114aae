"""Ground-truth evaluation of inbetweening (the analogue of Brodt & Bessmeltsev 2024, Table 1).

The paper compares its middle frames with hand-drawn in-betweens of a 1939 film. physlab
makes its own ground truth: :func:`physlab.inbetween.inbetween_benchmark` renders procedural
cartoon characters at two key poses *and at every intermediate pose*, so every in-between
has a true answer. The methods only see the two keyframe images, their skeletons and the
skeletal animation between them — never the renderer.

Methods compared (rows of the table):

* ``cross_dissolve`` — ``(1 − t)·key0 + t·key1``;
* ``flow`` — the frame interpolator alone between the two keys (the RIFE analogue, no
  skeleton): :func:`~physlab.inbetween.baselines.flow_interpolation`;
* ``physlab_diagonal`` — the skeletal pipeline with the naive blend α = t;
* ``physlab`` — the full pipeline with the blending optimisation.

Metrics (:mod:`physlab.inbetween.metrics`, images composited over white): PSNR (dB), SSIM,
and the Chamfer distance between dark pixels, reported ×10⁵ as in the paper (normalised by
the pixel count and the image diagonal — see :func:`~physlab.inbetween.metrics.chamfer`).
LPIPS needs pretrained AlexNet/VGG weights that cannot be fetched offline, so it is left
out (:func:`~physlab.inbetween.metrics.lpips_status`). Scores are given for the middle frame
(t = 0.5, the paper's protocol) and averaged over all in-betweens (keys excluded).

Skeleton interpolation between keys (``--interpolation``, :func:`compare_interpolation`):
the methods of :func:`~physlab.inbetween.skeleton.interpolate` against true in-between poses
from motion capture — Bandai-Namco clips on the procedural character, and the
AnimatedDrawings characters posed by their BVH motions — by joint error (px) and by the PSNR
of the in-betweens they drive, beside the in-between driven by the true animation and the
cross-dissolve.

Occlusions on real drawings (``--occluded --source animated_drawings``,
:func:`evaluate_occluded_drawings`): AnimatedDrawings characters posed by BVH motions whose hand
crosses the body (:data:`AD_OCCLUDED_SHOTS`, found by :func:`scan_occluded_shots`), occlusion
regions suggested by :func:`~physlab.inbetween.occlusion.suggest_occlusions`, their T-junctions
by :func:`~physlab.inbetween.occlusion.suggest_t_junctions` (``--no-t-junctions``: none) — or
grown to each limb's whole contact with the body (``--regions contact``,
:func:`~physlab.inbetween.occlusion.limb_contact`) — and joint depths from the BVH; physlab
layered vs one sheet vs the baselines against the posed drawing — deformed as one sheet
(``--truth sheet``, the default), or cut into body parts moved rigidly and painted by depth
(``--truth parts``, :mod:`~physlab.inbetween.cutout`), a truth that is not the one-sheet
method's own model.

One's own keyframe pair — two keys, their skeletons, and in-betweens drawn by hand where
there are some — is scored the same way by :func:`evaluate_folder` (``physlab evaluate
inbetween --pairs DIR``; the folder layout is :mod:`physlab.inbetween.pair_folder`'s).

Run ``python -m physlab.inbetween.evaluate --help``.
"""
from __future__ import annotations

import sys
import textwrap
import time
from functools import partial
from pathlib import Path
from typing import NamedTuple

import numpy as np

from . import metrics
from .baselines import cross_dissolve, flow_interpolation
from .blend import render_path
from .frame_interpolation import FlowInterpolator
from .pair_folder import DEFAULT_FRAMES, FOLDER_FORMAT, load_pair_folder
from .pipeline import _paper_colour, inbetween
from .skeleton import INTERPOLATION_METHODS, interpolate
from .template import as_rgba_float

__all__ = ["METHODS", "METRICS", "run_methods", "frame_scores", "score_frames",
           "comparison_sheet", "middle_sheet", "evaluate_pairs", "evaluate_folder", "summarize",
           "format_table",
           "AD_SHOTS", "pose_drawing", "animated_drawing_inbetween", "INTERPOLATION_SOURCES",
           "MOCAP_CLIPS", "CHARACTER_BANDAI_MAPPING", "InterpolationPair", "interpolation_pairs",
           "interpolation_errors", "interpolation_psnr", "interpolation_table",
           "compare_interpolation", "BODY_BONES", "LIMB_BONES", "CAPSULE_RADIUS",
           "AD_OCCLUDED_SHOTS", "OCCLUDED_TRUTHS", "DEFAULT_REGIONS", "limb_body_overlaps",
           "scan_occluded_shots",
           "OccludedDrawingPair", "occluded_drawing_pairs", "evaluate_occluded_drawings",
           "main"]

METHODS = ("cross_dissolve", "flow", "physlab_diagonal", "physlab")
#: Extra row of occluded pairs (kind "occluded"): physlab without the occlusion layers.
SINGLE_SHEET = "physlab_single_sheet"
METRICS = ("psnr", "ssim", "cd")
#: larger is better for these metrics (the rest: smaller is better)
HIGHER_IS_BETTER = {"psnr": True, "ssim": True, "cd": False}


def run_methods(key0, key1, skeleton0, skeleton1, n_frames, animation=None, interpolator=None,
                **options):
    """Frames of every method in :data:`METHODS` for one keyframe pair.

    Every method sees the same keys, as straight RGBA, and returns frames with the channels
    of the physlab result: 4 (straight RGBA) when a key has transparency, 3 for opaque keys
    (RGB, grey, or RGBA with alpha 1 everywhere) — :func:`~physlab.inbetween.pipeline.
    inbetween` composites those over the paper colour (the median background of the keys),
    and so are the baselines and the diagonal blend here, over the same colour.

    Parameters
    ----------
    key0, key1 : (H, W), (H, W, 3) or (H, W, 4) images, uint8 or float in [0, 1], same size.
    skeleton0, skeleton1, n_frames, animation, options : as for
        :func:`~physlab.inbetween.pipeline.inbetween`.
    interpolator : FrameInterpolator shared by the flow baseline and the pipeline (default
        ``FlowInterpolator()``).

    Returns
    -------
    frames : dict method → (n_frames, H, W, C) float32 (keys at both ends), the same C for
        every method.
    result : the :class:`~physlab.inbetween.pipeline.InbetweenResult` of the physlab run.
    seconds : dict method → wall time.
    """
    k0, k1 = as_rgba_float(key0, "key0"), as_rgba_float(key1, "key1")
    interp = FlowInterpolator() if interpolator is None else interpolator
    frames, seconds = {}, {}
    tic = time.perf_counter()
    res = inbetween(k0, k1, skeleton0, skeleton1, n_frames, animation=animation,
                    interpolator=interp, **options)
    seconds["physlab"] = time.perf_counter() - tic
    frames["physlab"] = res.frames
    tic = time.perf_counter()
    frames["cross_dissolve"] = cross_dissolve(k0, k1, n_frames)
    seconds["cross_dissolve"] = time.perf_counter() - tic
    tic = time.perf_counter()
    frames["flow"] = flow_interpolation(k0, k1, n_frames, interp)
    seconds["flow"] = time.perf_counter() - tic
    tic = time.perf_counter()
    diag = np.asarray(render_path(res.fwd, res.bwd, res.diagonal, interp), np.float32)
    diag[0], diag[-1] = k0, k1  # the keys exactly, as in the physlab result
    frames["physlab_diagonal"] = diag
    seconds["physlab_diagonal"] = seconds["physlab"] + time.perf_counter() - tic
    if res.frames.shape[-1] == 3:  # opaque keys: every method on the physlab result's paper
        paper = _result_paper(res)
        for m in ("cross_dissolve", "flow", "physlab_diagonal"):
            a = frames[m][..., 3:4]
            frames[m] = (frames[m][..., :3] * a + paper * (1.0 - a)).astype(np.float32)
    return frames, res, seconds


def _result_paper(result):
    """(3,) float32, the paper colour :func:`~physlab.inbetween.pipeline.inbetween` put behind
    the in-betweens of opaque keys: the mean of the keys' median background colours."""
    (t0, t1) = result.templates
    return np.float32(0.5) * (_paper_colour(t0.image, t0.mask) + _paper_colour(t1.image, t1.mask))


def frame_scores(frame, truth):
    """PSNR (dB), SSIM and Chamfer distance (×10⁵) of one frame against its ground truth.

    Parameters
    ----------
    frame, truth : (H, W[, C]) images of the same size (RGBA composited over white,
        :mod:`physlab.inbetween.metrics`).

    Returns
    -------
    dict ``{"psnr": float, "ssim": float, "cd": float}`` (keys: :data:`METRICS`).
    """
    return {"psnr": metrics.psnr(frame, truth), "ssim": metrics.ssim(frame, truth),
            "cd": metrics.chamfer(frame, truth, scale=metrics.CD_SCALE)}


def score_frames(frames, truth):
    """Metrics of a frame sequence against ground truth.

    Parameters
    ----------
    frames, truth : (n, H, W, C) images (n ≥ 3; keys at both ends are excluded).

    Returns
    -------
    dict ``{"<metric>_mid": float, "<metric>_all": float}`` for psnr, ssim, cd (CD ×10⁵);
    "mid" is frame ``n // 2`` (t = 0.5 for odd n), "all" the mean over frames 1..n−2.
    """
    n = len(frames)
    if len(truth) != n or n < 3:
        raise ValueError(f"need ≥ 3 frames and as many ground-truth frames, got {n} and "
                         f"{len(truth)}")
    per = [frame_scores(f, g) for f, g in zip(frames[1:-1], truth[1:-1])]
    out = {}
    for k in METRICS:
        out[f"{k}_mid"] = float(per[n // 2 - 1][k])
        out[f"{k}_all"] = float(np.mean([p[k] for p in per]))
    return out


def comparison_sheet(frames, truth=None, path=None, every=2, title=None):
    """Figure: ground truth and every method (rows) over time.

    Parameters
    ----------
    frames : dict method → (n, H, W, C) frames, keys included (:func:`run_methods`).
    truth : (n, H, W, C) ground truth of every frame; or a dict frame index → (H, W, C)
        image for the frames that have one (their columns are always shown, the row's other
        cells stay empty); or None (no ground-truth row).
    path : PNG file to write (atomically), or None.
    every : int ≥ 1, show every ``every``-th frame (and the last).
    title : str or None.

    Returns
    -------
    matplotlib Figure.
    """
    from .plots import over_white
    from ..viz.plots import new_figure

    n = len(frames[METHODS[0]])
    known = dict(truth) if isinstance(truth, dict) else {}
    idx = sorted(set(range(0, n, every)) | {n - 1} | set(known))
    rows = [(m, frames[m]) for m in METHODS + (SINGLE_SHEET,) if m in frames]
    if truth is not None and len(truth):
        rows.insert(0, ("ground truth", known or truth))
    H, W = np.asarray(frames[METHODS[0]][0]).shape[:2]
    fig, axes = new_figure(ncols=len(idx), nrows=len(rows), width=1.0, height=1.0 * H / W)
    axes = np.asarray(axes).reshape(len(rows), len(idx))
    for r, (name, seq) in enumerate(rows):
        for c, i in enumerate(idx):
            ax = axes[r, c]
            if not isinstance(seq, dict) or i in seq:
                ax.imshow(over_white(seq[i]))
            else:
                ax.set_facecolor("0.92")  # no ground truth at this frame
            ax.set_xticks([])
            ax.set_yticks([])
            if c == 0:
                ax.set_ylabel(name.replace("_", " "), fontsize=8)
            if r == len(rows) - 1:
                ax.set_xlabel(f"t = {i / (n - 1):.3g}", fontsize=8)
    if title:
        fig.suptitle(title, fontsize=8)
    if path is not None:
        from .._io import atomic_write

        atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=80), suffix=".png")
    return fig


def middle_sheet(middles, path=None, title=None):
    """Figure: one row per pair — both keys, the ground truth and every method at the middle
    frame (t = 0.5 for an odd frame count).

    Parameters
    ----------
    middles : dict pair name → dict with "key0", "key1", "truth", "t" and a (H, W, C) frame
        per method (:func:`evaluate_pairs` with ``middle=True``).
    path : PNG file to write (atomically), or None. title : str or None.

    Returns
    -------
    matplotlib Figure.
    """
    from .plots import over_white
    from ..viz.plots import new_figure

    if not isinstance(middles, dict) or not middles:
        raise ValueError("middles must be a non-empty dict pair name -> middle frames "
                         "(evaluate_pairs(..., middle=True))")
    methods = [m for m in METHODS + (SINGLE_SHEET,) if m in next(iter(middles.values()))]
    cols = ["key0", "key1", "truth"] + methods
    H, W = np.asarray(next(iter(middles.values()))["key0"]).shape[:2]
    fig, axes = new_figure(ncols=len(cols), nrows=len(middles), width=1.2,
                           height=1.2 * H / W)
    axes = np.asarray(axes).reshape(len(middles), len(cols))
    for r, (name, mid) in enumerate(middles.items()):
        for c, col in enumerate(cols):
            ax = axes[r, c]
            ax.imshow(over_white(mid[col]))
            ax.set_xticks([])
            ax.set_yticks([])
            if c == 0:
                ax.set_ylabel(name, fontsize=7)
            if r == 0:
                label = {"key0": "key 0", "key1": "key 1",
                         "truth": f"truth t = {mid['t']:.2g}"}.get(col, col.replace("_", " "))
                ax.set_title(label, fontsize=7)
    if title:
        fig.suptitle(title, fontsize=8)
    if path is not None:
        from .._io import atomic_write

        atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=100), suffix=".png")
    return fig


def evaluate_pairs(pairs, n_frames=11, progress=True, interpolator=None, sheets=None,
                   middle=False, **options):
    """Score every method on every benchmark pair.

    Parameters
    ----------
    pairs : iterable of pairs with ``name``, ``kind`` ("tight"/"far"), ``keyframes()``,
        ``skeleton0``, ``skeleton1``, ``animation(n)`` and ``ground_truth(t)``
        (:class:`physlab.inbetween.characters.InbetweenPair`).
    n_frames : int, frames per pair including both keys (9 in-betweens → 11).
    sheets : folder for a :func:`comparison_sheet` PNG per pair, or None.
    middle : bool, also return the middle frames (for :func:`middle_sheet`).
    options : passed to :func:`~physlab.inbetween.pipeline.inbetween`.

    Returns
    -------
    rows : list of dicts (pair, kind, method, seconds, metric values, and for "physlab" the
        largest handle error and flipped-triangle count; for "physlab" and "physlab_diagonal"
        also ``q_fwd_min``, ``q_bwd_min``, the lowest per-frame texture quality of each
        deformed sequence, Sec. 5.2 — 1 when no inpainted texel is visible).
    With ``middle``: ``(rows, middles)``, middles a dict pair name → {"key0", "key1",
    "truth", "t", method → frame} at frame ``n_frames // 2``.
    """
    pairs = list(pairs)
    it = pairs
    if progress:
        from tqdm.auto import tqdm

        it = tqdm(pairs, desc="pairs")
    rows, middles = [], {}
    t = np.linspace(0.0, 1.0, n_frames)
    for pair in it:
        key0, key1 = pair.keyframes()
        truth = np.asarray(pair.ground_truth(t))
        occluded = getattr(pair, "kind", "") == "occluded"
        extra = {}
        if occluded:  # layered templates from the true occlusions (Secs. 4.1–4.4)
            o0, o1 = pair.occlusions()
            extra = {"occlusions0": o0, "occlusions1": o1}
        frames, res, sec = run_methods(key0, key1, pair.skeleton0, pair.skeleton1, n_frames,
                                       animation=pair.animation(n_frames),
                                       interpolator=interpolator, **options, **extra)
        methods = list(METHODS)
        if occluded:  # the same pipeline as one sheet, for comparison
            import warnings

            tic = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                one = inbetween(key0, key1, pair.skeleton0, pair.skeleton1, n_frames,
                                animation=pair.animation(n_frames), interpolator=interpolator,
                                **options)
            frames[SINGLE_SHEET], sec[SINGLE_SHEET] = one.frames, time.perf_counter() - tic
            methods.append(SINGLE_SHEET)
        if sheets is not None:
            comparison_sheet(frames, truth, Path(sheets) / f"{pair.name}.png",
                             title=f"{pair.name} ({pair.kind}, {getattr(pair, 'style', '')})")
        if middle:
            i = n_frames // 2
            middles[pair.name] = {"key0": key0, "key1": key1, "truth": truth[i],
                                  "t": float(t[i]), **{m: frames[m][i] for m in methods}}
        for m in methods:
            row = {"pair": pair.name, "kind": pair.kind, "method": m, "seconds": sec[m]}
            row.update(score_frames(frames[m], truth))
            if m.startswith("physlab"):  # the one-sheet row from its own run
                r_m = one if m == SINGLE_SHEET else res
                row["handle_error_px"] = float(r_m.handle_error.max())
                row["flipped"] = int(r_m.flipped.sum())
            if m in ("physlab", "physlab_diagonal"):
                row["q_fwd_min"] = float(res.q_fwd.min())
                row["q_bwd_min"] = float(res.q_bwd.min())
            rows.append(row)
    return (rows, middles) if middle else rows


def evaluate_folder(folder, n_frames=None, out=None, progress=False, interpolator=None,
                    **options):
    """Every method on one's own keyframe pair, scored wherever ground truth exists.

    The folder is read by :func:`~physlab.inbetween.pair_folder.load_pair_folder`; its
    layout (:data:`~physlab.inbetween.pair_folder.FOLDER_FORMAT`, also in ``--help``)::

    {folder_format}

    Parameters
    ----------
    folder : str or Path of the pair folder.
    n_frames : int ≥ 3 or None (the folder's rule above).
    out : folder for ``contact.png`` (:func:`comparison_sheet`: ground truth where given and
        every method), and with ground truth ``table.md`` and ``rows.json``; None writes
        nothing.
    progress : bool, tqdm bars of the pipeline.
    interpolator : FrameInterpolator (default ``FlowInterpolator()``).
    options : passed to :func:`~physlab.inbetween.pipeline.inbetween`.

    Returns
    -------
    dict with "rows" (one per method and ground-truth frame: pair, t, method, psnr, ssim, cd
    ×10⁵, seconds), "summary" (``(group, method) → {{metric: value, "n"}}``, groups
    ``t=<t>`` and, with several ground truths, ``mean``), "table" (:func:`format_table`
    text, empty without ground truth), "frames", "result" (InbetweenResult), "seconds",
    "n_frames", "occlusions" (the keys' Occlusion lists or None), "files" (paths written).

    Raises
    ------
    FileNotFoundError, NotADirectoryError, ValueError naming the file that is missing or
    wrong (:func:`~physlab.inbetween.pair_folder.load_pair_folder`).
    """
    pair = load_pair_folder(folder)
    n = pair.n_frames(n_frames)
    truth = pair.truth_frames(n)
    frames, res, sec = run_methods(pair.key0, pair.key1, pair.skeleton0, pair.skeleton1, n,
                                   animation=pair.animation, interpolator=interpolator,
                                   progress=progress, occlusions0=pair.occlusions[0],
                                   occlusions1=pair.occlusions[1], **options)
    t = np.linspace(0.0, 1.0, n)
    rows, summary = [], {}
    for m in METHODS:
        per = []
        for i, gt in truth.items():
            scores = frame_scores(frames[m][i], gt)
            per.append(scores)
            rows.append({"pair": pair.name, "t": float(t[i]), "method": m, **scores,
                         "seconds": sec[m]})
            summary[f"t={t[i]:.3g}", m] = {**scores, "n": 1}
        if len(per) > 1:
            summary["mean", m] = {k: float(np.mean([p[k] for p in per])) for k in METRICS}
            summary["mean", m]["n"] = len(per)
    summary = {k: summary[k] for k in sorted(summary, key=lambda k: k[0] == "mean")}
    table = format_table(summary, columns=METRICS) if summary else ""
    files = []
    if out is not None:
        import json

        from .._io import atomic_write_text

        sheet = Path(out) / "contact.png"
        shown = {0: pair.key0, **truth, n - 1: pair.key1}  # the keys are true at t = 0, 1
        comparison_sheet(frames, shown, sheet, every=max(1, (n - 1) // 10),
                         title=f"{pair.name}: keys and ground truth (where given), every method")
        files.append(sheet)
        if table:
            files.append(atomic_write_text(Path(out) / "table.md", table + "\n"))
            files.append(atomic_write_text(Path(out) / "rows.json", json.dumps(rows, indent=1)))
    return {"rows": rows, "summary": summary, "table": table, "frames": frames, "result": res,
            "seconds": sec, "n_frames": n, "occlusions": pair.occlusions, "files": files}


# one source for the folder layout: FOLDER_FORMAT, shown in the docstring and in --help
if evaluate_folder.__doc__:  # None under python -OO
    evaluate_folder.__doc__ = evaluate_folder.__doc__.format(
        folder_format=textwrap.indent(FOLDER_FORMAT, "    ").lstrip())


def summarize(rows):
    """Mean of every metric per (kind, method): dict ``(kind, method) → {metric: mean}``.

    ``kind`` "all" pools every pair.
    """
    out = {}
    kinds = sorted({r["kind"] for r in rows}) + ["all"]
    keys = [f"{m}_{w}" for m in METRICS for w in ("mid", "all")]
    for kind in kinds:
        for m in METHODS + (SINGLE_SHEET,):
            sel = [r for r in rows if r["method"] == m and kind in (r["kind"], "all")]
            if sel:
                out[kind, m] = {k: float(np.mean([r[k] for r in sel])) for k in keys}
                out[kind, m]["n"] = len(sel)
    return out


def format_table(summary, columns=None):
    """Plain-text table of :func:`summarize` (best value per column and group in *stars*).

    ``columns`` : keys of the summary values to show, each ``<metric>`` or
    ``<metric>_<suffix>``; default the mid-frame and all-frame values of every metric."""
    cols = list(columns) if columns is not None else \
        [f"{m}_{w}" for w in ("mid", "all") for m in METRICS]
    head = ["group", "method", "n"] + [c.replace("_", " ") for c in cols]
    lines = [" | ".join(head), " | ".join("---" for _ in head)]
    for kind in dict.fromkeys(k for k, _ in summary):
        group = {m: v for (k, m), v in summary.items() if k == kind}
        best = {c: (max if HIGHER_IS_BETTER[c.split("_")[0]] else min)(g[c] for g in group.values())
                for c in cols}
        for m, v in group.items():
            cells = []
            for c in cols:
                s = f"{v[c]:.2f}" if not c.startswith("ssim") else f"{v[c]:.4f}"
                cells.append(f"*{s}*" if v[c] == best[c] else s)
            lines.append(" | ".join([kind, m, str(v["n"])] + cells))
    return "\n".join(lines)


# ----------------------------------------------------------------------------- real drawings
#: AnimatedDrawings character → (BVH motion, key time 0 [s], key time 1 [s]). Chosen by a scan
#: over the six motions (0.8 s windows, 0.1 s steps): the window with the largest local bone
#: rotation in which no two bones without a shared joint come closer than 1.2× the sum of
#: their drawn half-widths (mask distance transform at the bone midpoint) unless they already
#: are in the drawing — limbs never touch the body or each other, the occlusion-free case of
#: this part. char5 (six arms) and char6 (four legs) have no such window; their shots were
#: picked by eye.
AD_SHOTS = {
    "char1": ("jesse_dance", 9.1, 9.9),
    "char2": ("zombie", 0.8, 1.6),
    "char3": ("jumping", 1.2, 1.9),
    "char4": ("zombie", 0.8, 1.6),
    "char5": ("dab", 0.8, 1.6),
    "char6": ("jumping", 2.4, 3.2),
}


def pose_drawing(template, skeleton, **options):
    """Render a template in a new pose: a keyframe "drawn" from the original drawing.

    The template is deformed (symmetric Dirichlet, Eq. 1, with the continuation of
    :func:`~physlab.inbetween.pipeline.deform_sequence`) into ``skeleton`` and rendered.
    Returns ``(image (H, W, 4) float32, x (n, 2))``.
    """
    from .pipeline import deform_sequence

    xs = deform_sequence(template, [skeleton], **options)[0]
    return template.render(xs[0]), xs[0]


def animated_drawing_inbetween(name, motion=None, t0=None, t1=None, n_frames=11, pad=0.25,
                               progress=False, **options):
    """Inbetween a real AnimatedDrawings character between two BVH-posed keyframes.

    The drawing (``../shared/data``; MIT, © Meta Platforms) is padded by ``pad`` of its size
    on every side, posed with the BVH ``motion`` at times ``t0`` and ``t1`` (seconds;
    :data:`AD_SHOTS` defaults) by :func:`pose_drawing` — these are the two keyframes — and
    in-betweened with the BVH poses between them as the skeletal animation.

    Returns
    -------
    dict with "result" (InbetweenResult), "keys" (two images), "skeletons", "motion",
    "frames" (BVH frame numbers), "flipped" (int, all frames and both templates),
    "max_handle_error_px", "seconds".
    """
    from ..datasets import animated_drawing
    from .retarget import keyframe_poses, load_motion
    from .skeleton import Skeleton
    from .template import build_template

    d = animated_drawing(name)
    m0, a0, a1 = AD_SHOTS.get(name, (None, None, None))
    motion, t0, t1 = motion or m0, a0 if t0 is None else t0, a1 if t1 is None else t1
    if motion is None or t0 is None or t1 is None:
        raise ValueError(f"no default shot for {name!r}: pass motion, t0 and t1")
    H, W = d.image.shape[:2]
    p = int(round(pad * max(H, W)))
    img = np.pad(d.image, ((p, p), (p, p), (0, 0)))
    mask = np.pad(d.notes["mask"], p)
    sk = Skeleton(**d.notes["skeleton"])
    sk = sk.with_xy(sk.xy + p)
    bvh = load_motion(motion)
    f0, f1 = t0 * bvh.fps, t1 * bvh.fps
    if not (0 <= f0 < bvh.n_frames and 0 <= f1 < bvh.n_frames):
        raise ValueError(f"times {t0}, {t1} s lie outside the {bvh.duration:.1f} s of {motion!r}")
    poses = keyframe_poses(sk, bvh, f0, f1, n_inbetweens=n_frames - 2)
    tic = time.perf_counter()
    rest = build_template(img, sk, mask=mask)
    key0, _ = pose_drawing(rest, poses.key0)
    key1, _ = pose_drawing(rest, poses.key1)
    anim = [poses.key0, *poses.inbetweens, poses.key1]
    res = inbetween(key0, key1, poses.key0, poses.key1, n_frames, animation=anim,
                    progress=progress, **options)
    return {"result": res, "keys": (key0, key1), "skeletons": anim, "motion": motion,
            "frames": poses.frames, "flipped": int(res.flipped.sum()),
            "max_handle_error_px": float(res.handle_error.max()),
            "seconds": time.perf_counter() - tic}


# ------------------------------------------------------------ real drawings with occlusions
#: Drawing bones (named by their end joint's base name) that make up the body, and the
#: suffixes of limb bones; a "limb in front of the body" is a limb bone whose capsule meets
#: a body bone's (:func:`limb_body_overlaps`). The short shoulder and pelvis bones are not
#: body bones: a hand at its own shoulder is an arm folded on itself, at its hip an arm
#: hanging beside the body.
BODY_BONES = ("hip", "torso", "neck")
LIMB_BONES = ("_elbow", "_hand", "_knee", "_foot")
#: Capsule radius of the overlap test, as a fraction of the rest skeleton's extent (the
#: default of :func:`~physlab.inbetween.occlusion.suggest_occlusions`).
CAPSULE_RADIUS = 0.06

#: Occluded AnimatedDrawings shots: name → (character, BVH motion, key time 0 [s], key time 1
#: [s]). Chosen by :func:`scan_occluded_shots` (characters scaled to 256 px, 0.5 s windows
#: every 0.1 s over the six motions, ``view="front"``), the opposite of :data:`AD_SHOTS`'
#: scan: windows in which exactly one key has a limb bone whose capsule (radius
#: :data:`CAPSULE_RADIUS` of the skeleton's extent) overlaps a body bone's that it does not
#: overlap in the drawing itself, whose joints stay inside the image, and whose keys differ by
#: ≥ 10 % of the image; ranked by the overlap's depth (px). Kept: the best window of each
#: character with one body and two arms and legs (char1–char4; char5's six arms and char6's
#: four legs overlap each other), at most two shots per motion. In all four a hand crosses
#: the torso or neck at the second key (dab: the arm folds up across the chest; zombie: the
#: arms reach forward, in front of the body) or leaves it (char2's dab).
AD_OCCLUDED_SHOTS = {
    "char4_dab": ("char4", "dab", 3.7, 4.2),
    "char2_dab": ("char2", "dab", 4.7, 5.2),
    "char3_zombie": ("char3", "zombie", 1.4, 1.9),
    "char1_zombie": ("char1", "zombie", 1.4, 1.9),
}
#: Ground truths of :class:`OccludedDrawingPair`: the rest drawing deformed as one sheet into
#: each pose, or cut into body parts moved rigidly (:mod:`~physlab.inbetween.cutout`).
OCCLUDED_TRUTHS = ("sheet", "parts")
#: Extent of the suggested regions of :class:`OccludedDrawingPair` (``extent`` of
#: :func:`~physlab.inbetween.occlusion.suggest_occlusions`): ``"capsule"`` overlaps, or the
#: limb's whole ``"contact"`` with the body.
DEFAULT_REGIONS = "capsule"


def _bone_capsules(skeleton):
    """Bones as segments: ``(names (B,), a (B, 2), b (B, 2), bones (B, 2))``."""
    bones = skeleton.bones
    return ([skeleton.names[c] for _, c in bones], skeleton.xy[bones[:, 0]],
            skeleton.xy[bones[:, 1]], bones)


def limb_body_overlaps(skeleton, rest, radius):
    """Limb bones whose capsule overlaps a body bone's in ``skeleton`` but not in ``rest``.

    Capsules of radius ``radius`` px around every bone (named by its end joint); limb bones
    end in ``*_elbow``, ``*_hand``, ``*_knee``, ``*_foot`` (:data:`LIMB_BONES`, extra-limb
    suffixes allowed), body bones are :data:`BODY_BONES`. Pairs that already overlap in the
    drawing's own pose ``rest`` (a thigh meeting the belly) are not occlusions the motion made.

    Parameters
    ----------
    skeleton : Skeleton, the posed joints (pixels).
    rest : Skeleton of the same topology, the drawing's own pose (pixels, same scale).
    radius : float > 0, capsule radius (px).

    Returns
    -------
    list of ``(limb joint, body joint, overlap px)``, overlap = ``2·radius − distance`` > 0,
    deepest first.

    Raises
    ------
    ValueError for a radius that is not a positive number; the errors of
    :func:`~physlab.inbetween.skeleton.check_compatible` for skeletons that differ.
    """
    from .occlusion import _segment_distance
    from .retarget import _base_name
    from .skeleton import Skeleton, check_compatible

    if not isinstance(skeleton, Skeleton) or not isinstance(rest, Skeleton):
        raise TypeError(f"skeleton and rest must be Skeletons, got {type(skeleton).__name__} "
                        f"and {type(rest).__name__}")
    check_compatible(rest, skeleton, ("rest", "skeleton"))
    if isinstance(radius, bool) or not isinstance(radius, (int, float, np.number)) \
            or not np.isfinite(radius) or radius <= 0:
        raise ValueError(f"radius must be a positive number of pixels, got {radius!r}")
    names, _, _, bones = _bone_capsules(skeleton)
    base = [_base_name(n) for n in names]
    limbs = [i for i, b in enumerate(base) if b.endswith(LIMB_BONES)]
    body = [i for i, b in enumerate(base) if b in BODY_BONES]
    out = []
    for i in limbs:
        for j in body:
            if set(bones[i].tolist()) & set(bones[j].tolist()):
                continue  # bones sharing a joint (the upper arm and the shoulder bone)
            gap = [2 * radius - _segment_distance(*s.xy[bones[i]], *s.xy[bones[j]])
                   for s in (skeleton, rest)]
            if gap[0] > 0 and gap[1] <= 0:
                out.append((names[i], names[j], float(gap[0])))
    return sorted(out, key=lambda o: -o[2])


def scan_occluded_shots(characters=None, motions=None, size=256, span=0.5, step=0.1,
                        margin=0.04, min_move=0.1):
    """Scan the AnimatedDrawings characters × BVH motions for keyframe pairs with a limb in
    front of (or behind) the body — how :data:`AD_OCCLUDED_SHOTS` was chosen.

    Every window ``[t0, t0 + span]`` (seconds, starting every ``step`` from the motion's
    AnimatedDrawings start frame) poses the character scaled to ``size`` px
    (``view="front"``) at its two keys and 3 in-betweens. A window qualifies when exactly one
    key has :func:`limb_body_overlaps` (capsule radius :data:`CAPSULE_RADIUS` of the rest
    skeleton's extent) — the limb swings onto or off the body —, every joint stays ``margin``
    of the image inside it, and some joint moves ≥ ``min_move`` of the image between the keys.

    Parameters
    ----------
    characters : iterable of names in ``physlab.datasets.ANIMATED_DRAWINGS`` (default all).
    motions : iterable of names in :data:`~physlab.inbetween.retarget.ANIMATED_DRAWINGS_MOTIONS`
        (default all).
    size : int ≥ 64, image size (px). span, step : float > 0, seconds.
    margin, min_move : floats in [0, 0.5), fractions of ``size``.

    Returns
    -------
    list of dicts (character, motion, t0, t1, key (0 or 1, the overlapping key), overlaps
    (:func:`limb_body_overlaps` of that key), overlap_px (the deepest), move_px), the best
    window per (character, motion), deepest overlap first.

    Raises
    ------
    ValueError naming the argument for unknown names or out-of-range numbers;
    FileNotFoundError when the external data folder is missing.
    """
    from ..datasets import ANIMATED_DRAWINGS
    from .retarget import (ANIMATED_DRAWINGS_MOTIONS, ANIMATED_DRAWINGS_START_FRAMES,
                           bvh_to_skeletons, load_motion)

    characters = ANIMATED_DRAWINGS if characters is None else tuple(characters)
    motions = tuple(ANIMATED_DRAWINGS_MOTIONS) if motions is None else tuple(motions)
    for arg, names, known in (("characters", characters, ANIMATED_DRAWINGS),
                              ("motions", motions, tuple(ANIMATED_DRAWINGS_MOTIONS))):
        bad = [n for n in names if n not in known]
        if bad or not names:
            raise ValueError(f"{arg} must be a non-empty list of {known}, got unknown {bad}"
                             if bad else f"{arg} is empty; give at least one of {known}")
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 64:
        raise ValueError(f"size must be an int ≥ 64 (px), got {size!r}")
    for arg, v, lo, hi in (("span", span, 0.0, np.inf), ("step", step, 0.0, np.inf),
                           ("margin", margin, -1e-12, 0.5), ("min_move", min_move, -1e-12, 0.5)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.number)) or \
                not lo < v < hi:
            raise ValueError(f"{arg} must be a number in ({max(lo, 0):g}, {hi:g}), got {v!r}")
    out = []
    for name in characters:
        img, _, rest = _scaled_drawing(name, size)
        H, W = img.shape[:2]
        radius = CAPSULE_RADIUS * float(np.ptp(rest.xy, axis=0).max())
        lo, hi = margin * size, np.array([W, H]) - 1 - margin * size
        for motion in motions:
            bvh = load_motion(motion)
            ref = ANIMATED_DRAWINGS_START_FRAMES[motion]
            n_f = int(round(span * bvh.fps))
            starts = np.arange(ref, bvh.n_frames - 1 - n_f, max(1, int(round(step * bvh.fps))))
            if not len(starts):
                continue
            frames = (starts[:, None] + np.linspace(0, n_f, 5)[None]).ravel()
            sks = bvh_to_skeletons(bvh, rest, frames=frames, reference_frame=ref)
            best = None
            for w, f0 in enumerate(starts):
                win = sks[5 * w:5 * w + 5]
                xy = np.stack([s.xy for s in win])
                if (xy < lo).any() or (xy > hi).any():
                    continue
                move = float(np.linalg.norm(xy[-1] - xy[0], axis=1).max())
                if move < min_move * size:
                    continue
                ov = [limb_body_overlaps(win[k], rest, radius) for k in (0, -1)]
                if bool(ov[0]) == bool(ov[1]):
                    continue
                key = 0 if ov[0] else 1
                depth = ov[key][0][2]
                if best is None or depth > best["overlap_px"]:
                    best = {"character": name, "motion": motion,
                            "t0": round(float(f0 / bvh.fps), 3),
                            "t1": round(float((f0 + n_f) / bvh.fps), 3), "key": key,
                            "overlaps": ov[key], "overlap_px": depth, "move_px": move}
            if best is not None:
                out.append(best)
    return sorted(out, key=lambda r: -r["overlap_px"])


class OccludedDrawingPair:
    """An AnimatedDrawings character posed by a BVH motion at two keys between which a limb
    swings onto or off the body — a pair of kind "occluded" for :func:`evaluate_pairs`.

    Ground truth follows the :func:`animated_drawing_inbetween` route: the drawing (padded,
    scaled to ``size``) is the rest template, deformed into the BVH pose at every time
    (:func:`pose_drawing`, each frame from the rest pose) — the keys are its frames at t = 0
    and 1. Unlike that route the template is rendered back to front by the joints' depths
    along the camera axis (:func:`~physlab.inbetween.retarget.bvh_joint_depths`; a
    :class:`~physlab.inbetween.occlusion.LayeredTemplate` without regions, painter's order of
    Sec. 5.1), so a limb the actor holds in front of the body is drawn over it, one held behind
    under it. The drawing itself has no occlusion, so its single sheet deforms cleanly — but
    it is the model of the one-sheet method, and where an arm folds across the chest the sheet
    between them is pulled into a spike in the truth itself. ``truth="parts"`` is a second,
    independent truth: the rest drawing cut into body parts, each moved rigidly by its bones
    and painted back to front by the BVH joint depths (:mod:`~physlab.inbetween.cutout`, the
    cut-out / paper-doll model; :attr:`parts`), so a limb crossing the body occludes it
    cleanly. Either way the keys are the truth at t = 0 and 1, and all methods get the same.

    The occlusion annotation is made without a human (:meth:`occlusions`):
    :func:`~physlab.inbetween.occlusion.suggest_occlusions` on each key, kept where its bone
    pair is one of the key's :func:`limb_body_overlaps` (a limb on the body that the drawing
    does not have), overlapping suggestions merged; each merged region gets the T-junctions of
    :func:`~physlab.inbetween.occlusion.suggest_t_junctions` (its bones' capsules, the nearer
    bones by BVH depth as the occluder; ``t_junctions=False``: none, as before 2026-11-26);
    with ``regions="contact"`` a limb's region is grown to its contact with the body and
    keeps :func:`~physlab.inbetween.occlusion.limb_contact`'s T-junctions (where it overlaps
    no other region); joint depths from the BVH.

    Parameters
    ----------
    name : str. character : "char1" … "char6". motion : a name of
        :data:`~physlab.inbetween.retarget.ANIMATED_DRAWINGS_MOTIONS`.
    t0, t1 : key times (seconds). size : int ≥ 64, the image's larger side (px).
    t_junctions : bool, suggest T-junctions for the regions (default True).
    rest_widths : bool, give each bone's capsule the half-width its limb is drawn with in the
        character's rest drawing (:func:`~physlab.inbetween.occlusion.bone_widths`) instead of
        one radius for all bones (default False: on these four shots the drawn widths lost
        0.6 dB at t = 0.5 and 1.6 dB over the sequence, docs/occlusion_experiments.md).
    truth : :data:`OCCLUDED_TRUTHS` ``"sheet"`` (default: the posed one-sheet template) or
        ``"parts"`` (the cut-out paper doll).
    regions : ``"capsule"`` (the capsule overlaps) or ``"contact"`` (each limb's region grown
        to its whole contact with the body, one region per limb with its own T-junctions:
        ``suggest_occlusions(extent="contact")``, :func:`~physlab.inbetween.occlusion.
        limb_contact`); default :data:`DEFAULT_REGIONS`.
    up : bool, with ``regions="contact"`` grow a limb's region along the whole limb, upper arm
        included (``suggest_occlusions(up=True)``; default False: from the overlapping bone
        down).
    by_limb : bool, with ``regions="contact"`` put each region's limb handles on one layer, by
        bone (``suggest_occlusions(by_limb=True)``, :attr:`~physlab.inbetween.occlusion.
        Occlusion.limb`) instead of splitting them at the largest depth gap (default False).

    Raises
    ------
    ValueError naming the argument for an unknown character or motion, times outside the
    motion, a bad size, truth, regions, up or by_limb; FileNotFoundError when the external data
    folder is missing.
    """

    kind = "occluded"

    def __init__(self, name, character, motion, t0, t1, size=256, t_junctions=True,
                 rest_widths=False, truth="sheet", regions=DEFAULT_REGIONS, up=False,
                 by_limb=False):
        from ..datasets import ANIMATED_DRAWINGS
        from .retarget import (ANIMATED_DRAWINGS_MOTIONS, ANIMATED_DRAWINGS_START_FRAMES,
                               load_motion)

        if character not in ANIMATED_DRAWINGS:
            raise ValueError(f"character must be one of {ANIMATED_DRAWINGS}, got {character!r}")
        if motion not in ANIMATED_DRAWINGS_MOTIONS:
            raise ValueError(f"motion must be one of {sorted(ANIMATED_DRAWINGS_MOTIONS)}, got "
                             f"{motion!r}")
        if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 64:
            raise ValueError(f"size must be an int ≥ 64 (px), got {size!r}")
        _check_truth(truth)
        self.regions = _check_regions(regions)
        for arg, v in (("up", up), ("by_limb", by_limb)):
            if not isinstance(v, (bool, np.bool_)):
                raise ValueError(f"{arg} must be True or False, got {v!r}")
            if v and self.regions != "contact":
                raise ValueError(f"{arg}=True is for regions='contact', got "
                                 f"regions={regions!r}")
        self.up, self.by_limb = bool(up), bool(by_limb)
        self.bvh = load_motion(motion)
        self.ref = ANIMATED_DRAWINGS_START_FRAMES[motion]
        for arg, t in (("t0", t0), ("t1", t1)):
            if isinstance(t, bool) or not isinstance(t, (int, float, np.number)) or \
                    not 0 <= t * self.bvh.fps <= self.bvh.n_frames - 1:
                raise ValueError(f"{arg} must be a time in [0, {self.bvh.duration:.2f}] s of "
                                 f"{motion!r}, got {t!r}")
        self.name, self.character, self.motion = name, character, motion
        self.t0, self.t1, self.size, self.truth = float(t0), float(t1), int(size), truth
        self.style = f"{character} · {motion} {t0:g}–{t1:g} s, {truth} truth"
        self.image, self.mask, self.rest = _scaled_drawing(character, self.size)
        if not isinstance(t_junctions, (bool, np.bool_)):
            raise ValueError(f"t_junctions must be True or False, got {t_junctions!r}")
        self.t_junctions = bool(t_junctions)
        if not isinstance(rest_widths, (bool, np.bool_)):
            raise ValueError(f"rest_widths must be True or False, got {rest_widths!r}")
        self.radius = CAPSULE_RADIUS * float(np.ptp(self.rest.xy, axis=0).max())
        self.widths = None
        if rest_widths:  # the limbs' drawn half-widths, measured where they are free
            from .occlusion import bone_widths

            self.widths = bone_widths(self.rest, self.mask)
        self.skeleton0, self.skeleton1 = self.skeleton_at([0.0, 1.0])
        self._template, self._parts, self._frames, self._occlusions = None, None, {}, None

    def __repr__(self):
        return f"OccludedDrawingPair({self.name!r}, {self.style}, size={self.size})"

    @property
    def parts(self):
        """The rest drawing cut into body parts (:func:`~physlab.inbetween.cutout.segment_parts`,
        computed once): the ``"parts"`` truth's paper doll."""
        if self._parts is None:
            from .cutout import segment_parts

            self._parts = segment_parts(self.mask, self.rest)
        return self._parts

    def skeleton_at(self, t):
        """Skeletons (with BVH joint depths) at times ``t`` (m,) in [0, 1] of the shot."""
        from .retarget import bvh_joint_depths, bvh_to_skeletons

        ts = np.atleast_1d(np.asarray(t, dtype=float))
        if ts.ndim != 1 or not np.all((ts >= 0) & (ts <= 1)):
            raise ValueError(f"t must lie in [0, 1], got {t}")
        frames = (self.t0 + ts * (self.t1 - self.t0)) * self.bvh.fps
        sks = bvh_to_skeletons(self.bvh, self.rest, frames=frames, reference_frame=self.ref)
        depth = bvh_joint_depths(self.bvh, self.rest, frames=frames, reference_frame=self.ref)
        return [s.with_depth(d) for s, d in zip(sks, depth)]

    def animation(self, n_frames):
        """The BVH skeletal motion: ``n_frames`` Skeletons at ``t = linspace(0, 1, n)``."""
        if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)) \
                or n_frames < 2:
            raise ValueError(f"n_frames must be an int >= 2, got {n_frames!r}")
        return self.skeleton_at(np.linspace(0.0, 1.0, int(n_frames)))

    def ground_truth(self, t):
        """The drawing posed at time(s) ``t``: (H, W, 4) float32 RGBA, or (m, H, W, 4) — the
        one sheet deformed (``truth="sheet"``) or the cut-out parts moved rigidly
        (``truth="parts"``, :func:`~physlab.inbetween.cutout.render_cutout`)."""
        from .cutout import render_cutout
        from .occlusion import build_layered_template

        if self.truth == "sheet" and self._template is None:
            self._template = build_layered_template(self.image, self.rest, (), mask=self.mask,
                                                    name=self.character)
        ts = np.atleast_1d(np.asarray(t, dtype=float))
        todo = [x for x in ts if float(x) not in self._frames]
        if todo:
            for x, s in zip(todo, self.skeleton_at(todo)):
                if self.truth == "parts":
                    self._frames[float(x)] = render_cutout(self.image, self.parts, self.rest, s)
                    continue
                _, xs = pose_drawing(self._template, s)
                self._frames[float(x)] = self._template.render(xs, skeleton=s)
        out = np.stack([self._frames[float(x)] for x in ts])
        return out if np.ndim(t) else out[0]

    def keyframes(self):
        """The two keys, (H, W, 4) float32 RGBA: the ground truth at t = 0 and 1."""
        return self.ground_truth(0.0), self.ground_truth(1.0)

    def occlusions(self):
        """Suggested occlusion regions of both keys: ``(list, list)`` of
        :class:`~physlab.inbetween.occlusion.Occlusion` (class docstring; computed once)."""
        if self._occlusions is None:
            self._occlusions = self._suggest_occlusions()
        return self._occlusions

    def _suggest_occlusions(self):
        from scipy import ndimage

        from .occlusion import Occlusion, suggest_occlusions, suggest_t_junctions

        out = []
        for key, sk in zip(self.keyframes(), (self.skeleton0, self.skeleton1)):
            fg = key[..., 3] > 0.5
            pairs = [o[:2] for o in limb_body_overlaps(sk, self.rest, self.radius)]
            sug = suggest_occlusions(key, sk, radius=self.radius, mask=fg, widths=self.widths,
                                     t_junctions=self.t_junctions and self.regions == "contact",
                                     extent=self.regions, up=self.up, by_limb=self.by_limb,
                                     pairs=pairs) if pairs else []
            # overlapping suggestions (one hand on torso and neck) become one region: the
            # layered template takes at most two layers per region
            if not sug:
                out.append([])
                continue
            union = np.any([o.mask for o in sug], axis=0)
            comps, k = ndimage.label(union)
            regs = []
            for c in range(1, k + 1):
                m = comps == c
                hit = [o for o in sug if (o.mask & m).any()]
                names = [o.label for o in hit]
                if len(hit) == 1 and self.regions == "contact":   # its own T-junctions
                    regs.append(Occlusion(m, hit[0].t_junctions, label=hit[0].label,
                                          limb=hit[0].limb))
                elif m.sum() >= 16:
                    tj = ()
                    if self.t_junctions:
                        bones = list(dict.fromkeys(j for n in names for p in n.split("+")
                                                   for j in p.split("/")))
                        tj = suggest_t_junctions(m, sk, bones, self.radius, fg,
                                                 widths=self.widths)
                    regs.append(Occlusion(m, tj, label="+".join(names)))
            out.append(regs)
        return tuple(out)


def _check_regions(regions):
    from .occlusion import REGION_EXTENTS

    if not isinstance(regions, str) or regions not in REGION_EXTENTS:
        raise ValueError(f"regions must be one of {REGION_EXTENTS} (capsule overlaps, or the "
                         f"limb's whole contact with the body), got {regions!r}")
    return regions


def _check_truth(truth):
    if not isinstance(truth, str) or truth not in OCCLUDED_TRUTHS:
        raise ValueError(f"truth must be one of {OCCLUDED_TRUTHS} (the posed one-sheet "
                         f"template, or the drawing cut into rigid parts), got {truth!r}")
    return truth


def occluded_drawing_pairs(shots=None, size=256, t_junctions=True, rest_widths=False,
                           truth="sheet", regions=DEFAULT_REGIONS, up=False, by_limb=False):
    """:class:`OccludedDrawingPair` of every shot (default :data:`AD_OCCLUDED_SHOTS`)."""
    shots = AD_OCCLUDED_SHOTS if shots is None else shots
    if not isinstance(shots, dict) or not shots:
        raise ValueError("shots must be a non-empty dict name -> (character, motion, t0, t1), "
                         f"got {shots!r}")
    _check_truth(truth)
    return [OccludedDrawingPair(name, *shot, size=size, t_junctions=t_junctions,
                                rest_widths=rest_widths, truth=truth, regions=regions,
                                up=up, by_limb=by_limb)
            for name, shot in shots.items()]


def evaluate_occluded_drawings(shots=None, size=256, n_frames=11, out=None, progress=True,
                               t_junctions=True, rest_widths=False, truth="sheet",
                               regions=DEFAULT_REGIONS, up=False, by_limb=False, **options):
    """Occlusion evaluation on real drawings (issue 15): every :func:`occluded_drawing_pairs`
    pair through :func:`evaluate_pairs` — physlab with layered templates from the suggested
    occlusions, physlab as one sheet, cross-dissolve, flow — scored against the posed drawing.

    Parameters
    ----------
    shots : dict name → (character, motion, t0, t1), default :data:`AD_OCCLUDED_SHOTS`.
    size : int ≥ 64, image size (px). n_frames : int ≥ 3, frames per pair, keys included.
    out : folder for ``table.md``, ``rows.json``, ``contact.png`` (:func:`middle_sheet`: keys,
        truth and every method at t = 0.5, one row per pair) and a :func:`comparison_sheet`
        per pair (``pairs/<name>.png``), or None.
    progress : bool. rest_widths : bool, per-bone capsule radii (:class:`OccludedDrawingPair`).
    t_junctions : bool, suggested T-junctions on the suggested regions
    (:class:`OccludedDrawingPair`). truth : ``"sheet"`` (the posed one-sheet drawing, default)
    or ``"parts"`` (the drawing cut into rigid parts; :class:`OccludedDrawingPair`).
    regions : ``"capsule"`` or ``"contact"``, the suggested regions' extent; up, by_limb : the
    contact regions along the whole limb, the limb's handles on one layer
    (:class:`OccludedDrawingPair`).
    options : passed to :func:`~physlab.inbetween.pipeline.inbetween`.

    Returns
    -------
    dict with "rows" (:func:`evaluate_pairs` rows plus ``regions0``/``regions1``, the number of
    suggested occlusion regions per key), "table" (metrics, :func:`format_table`), "physlab"
    (per pair and variant: largest handle error, flipped triangles, seconds), "files", and
    "skipped" (a reason, when the external data folder is missing: then nothing else is run).
    """
    from ..datasets import external_data_dir

    _check_truth(truth)
    if external_data_dir() is None:
        return {"rows": [], "table": "", "physlab": "", "files": [],
                "skipped": "external data folder not found (set PHYSLAB_EXTERNAL_DATA or "
                           "provide ../shared/data with animated_drawings/)"}
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)) or n_frames < 3:
        raise ValueError(f"n_frames must be an int ≥ 3 (keys included), got {n_frames!r}")
    pairs = occluded_drawing_pairs(shots, size, t_junctions, rest_widths, truth, regions, up,
                                   by_limb)
    sheets = None if out is None else Path(out) / "pairs"
    rows, middles = evaluate_pairs(pairs, n_frames=n_frames, progress=progress, sheets=sheets,
                                   middle=True, **options)
    regions = {p.name: [len(o) for o in p.occlusions()] for p in pairs}
    for r in rows:
        r["regions0"], r["regions1"] = regions[r["pair"]]
        r["truth"] = truth
    summary = {k: v for k, v in summarize(rows).items() if k[0] == "occluded"}
    table = format_table(summary)
    lines = ["pair | regions key0/key1 | variant | max handle error px | flipped | s",
             "--- | --- | --- | --- | --- | ---"]
    for r in rows:
        if r["method"] in ("physlab", SINGLE_SHEET):
            lines.append(f"{r['pair']} | {r['regions0']}/{r['regions1']} | "
                         f"{'layered' if r['method'] == 'physlab' else 'one sheet'} | "
                         f"{r['handle_error_px']:.2f} | {r['flipped']} | {r['seconds']:.1f}")
    stats = "\n".join(lines)
    files = []
    if out is not None:
        import json

        from .._io import atomic_write_text

        files.append(atomic_write_text(Path(out) / "table.md", table + "\n\n" + stats + "\n"))
        files.append(atomic_write_text(Path(out) / "rows.json", json.dumps(rows, indent=1)))
        middle_sheet(middles, Path(out) / "contact.png",
                     title=f"keys, {truth} truth and every method at the middle frame")
        files.append(Path(out) / "contact.png")
        files += [sheets / f"{p.name}.png" for p in pairs]
    return {"rows": rows, "table": table, "physlab": stats, "files": files, "skipped": None}


# ----------------------------------------------------------------------------- interpolation
#: Where the true skeletal animation between two keys comes from (:func:`interpolation_pairs`).
INTERPOLATION_SOURCES = ("procedural", "mocap", "animated_drawings")
#: Bandai-Namco clips (``dataset-1_<content>_normal_001.bvh``; CC BY-NC 4.0, © 2022 Bandai
#: Namco Research Inc.) that drive the procedural character for the ``"mocap"`` source.
MOCAP_CLIPS = ("walk", "kick", "punch", "slash", "byebye", "bow", "call", "dance-short")
#: Procedural character joint → (proximal, distal) Bandai-Namco joint whose projected segment
#: orients the bone into it (:func:`~physlab.inbetween.retarget.bvh_to_skeletons`); clavicles
#: and hip bones keep their rest angle relative to the trunk.
CHARACTER_BANDAI_MAPPING = {
    "chest": ("Hips", "Chest"), "neck": ("Chest", "Neck"), "head_top": ("Head", "Head_End"),
    **{f"{side}_{joint}": (f"{a}_{s}", f"{b}_{s}") for side, s in (("left", "L"), ("right", "R"))
       for joint, a, b in (("elbow", "UpperArm", "LowerArm"), ("hand", "LowerArm", "Hand"),
                           ("knee", "UpperLeg", "LowerLeg"), ("foot", "LowerLeg", "Foot"))}}
#: at most this many key pairs (windows) per clip or drawing, spread evenly over the motion
MAX_WINDOWS = 40
#: reference rows of the interpolation table beside the methods: the in-between driven by the
#: true skeletal animation (``animation=``), and the cross-dissolve of the keys
INTERPOLATION_REFERENCES = ("true_animation", "cross_dissolve")


class InterpolationPair(NamedTuple):
    """Two key skeletons and the true skeletal animation between them.

    ``truth`` : list of n Skeletons at ``t = linspace(0, 1, n)``, the keys at both ends.
    ``images`` : None, or a function ``() -> (key0, key1, middle)`` of the two key drawings
    and the true drawing at t = ½ (RGBA images of one size), for the PSNR of in-betweens.
    """

    name: str
    source: str
    truth: list
    images: object = None


def _bandai_motion(content):
    """The Bandai-Namco clip ``dataset-1_<content>_normal_001`` without its ``joint_Root``
    (fixed at the origin in these files), so that the Hips carry the root motion."""
    from physlab.motion.bvh import BVHMotion, read_bvh
    from physlab.motion.dataset import bandai_namco_dir

    m = read_bvh(bandai_namco_dir() / "dataset" / "Bandai-Namco-Research-Motiondataset-1"
                 / "data" / f"dataset-1_{content}_normal_001.bvh")
    k = len(m.channels[0])
    return BVHMotion(m.names[1:], m.parents[1:] - 1, m.offsets[1:], m.channels[1:],
                     m.frame_time, m.motion[:, k:])


def _window_starts(first, last, span, anchor=None):
    """Start frames of windows ``[f, f + span]`` inside ``[first, last]``, every ``span / 2``
    (through ``anchor`` when given): at most :data:`MAX_WINDOWS` spread evenly, plus
    ``anchor``."""
    a = first if anchor is None else anchor
    k = np.arange(np.ceil((first - a) / (span / 2)), np.floor((last - span - a) / (span / 2)) + 1)
    starts = a + k * span / 2
    if len(starts) > MAX_WINDOWS:
        starts = starts[np.round(np.linspace(0, len(starts) - 1, MAX_WINDOWS)).astype(int)]
    return starts if anchor is None else np.union1d(starts, [anchor])


def _posed_windows(bvh, skeleton, starts, span, n, **retarget):
    """(len(starts), n) Skeletons: ``skeleton`` posed at ``linspace(f, f + span, n)``."""
    from .retarget import bvh_to_skeletons

    frames = (starts[:, None] + np.linspace(0.0, span, n)).ravel()
    sks = bvh_to_skeletons(bvh, skeleton, frames=frames, **retarget)
    return [sks[i * n:(i + 1) * n] for i in range(len(starts))]


def _procedural_pairs(size, n):
    from .characters import inbetween_benchmark

    return [InterpolationPair(p.name, "procedural", p.animation(n),
                              lambda p=p: (*p.keyframes(), p.ground_truth(0.5)))
            for p in inbetween_benchmark(size)]


def _centred(truth, size, margin):
    """``truth`` translated so the joints' bounding box is centred in the image, or None when
    it does not fit ``margin`` px inside the image."""
    xy = np.concatenate([s.xy for s in truth])
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    if np.any(hi - lo > size - 1 - 2 * margin):
        return None
    shift = (size - 1) / 2 - (lo + hi) / 2
    return [s.with_xy(s.xy + shift) for s in truth]


def _image_window(windows, size):
    """Index of the window a clip shows as images: among the windows that fit the image and
    whose keys differ at least as much as the clip's median window (largest joint move), the
    one whose poses overlap least (:func:`~physlab.inbetween.characters.part_overlaps`
    pixels: real motion puts hands on the body and crosses the legs, which a single-sheet
    template cannot separate). Returns ``(index, centred skeletons)`` or ``(None, None)``."""
    from .characters import part_overlaps

    move = np.array([np.linalg.norm(w[-1].xy - w[0].xy, axis=1).max() for w in windows])
    best, shown, least = None, None, np.inf
    for i in np.flatnonzero(move >= np.median(move)):
        moved = _centred(windows[i], size, margin=0.08 * size)
        if moved is None:
            continue
        overlap = sum(k for s in moved for *_, k in part_overlaps(s, size))
        if overlap < least:
            best, shown, least = int(i), moved, overlap
    return best, shown


def _mocap_pairs(size, n, gap):
    """Windows of :data:`MOCAP_CLIPS` on the procedural character (front/side views by PCA
    of the limbs' motion, ``view="auto"``); one window per clip (:func:`_image_window`) also
    gets images (:func:`~physlab.inbetween.characters.render_character`)."""
    from .characters import CHARACTER_STYLES, character_skeleton, render_character

    rest = character_skeleton(size)
    out = []
    for c, content in enumerate(MOCAP_CLIPS):
        bvh = _bandai_motion(content)
        span = gap * bvh.fps
        starts = _window_starts(0.0, bvh.n_frames - 1, span)
        windows = _posed_windows(bvh, rest, starts, span, n, mapping=CHARACTER_BANDAI_MAPPING,
                                 view="auto")
        shown, centred = _image_window(windows, size)
        if shown is not None:
            windows[shown] = centred
        style = CHARACTER_STYLES[c % len(CHARACTER_STYLES)]

        def images(truth, style=style, seed=c):
            return (render_character(truth[0], style, size, seed),
                    render_character(truth[-1], style, size, seed),
                    render_character(truth[len(truth) // 2], style, size, seed))

        for i, (f0, truth) in enumerate(zip(starts, windows)):
            out.append(InterpolationPair(f"{content}@{f0:.0f}", "mocap", truth,
                                         partial(images, truth) if i == shown else None))
    return out


def _scaled_drawing(name, size, pad=0.25):
    """An AnimatedDrawings character padded by ``pad`` of its size and scaled to fit
    ``size`` px: ``(image (h, w, 4) uint8, mask (h, w) bool, Skeleton)``."""
    from PIL import Image

    from ..datasets import animated_drawing
    from .skeleton import Skeleton

    d = animated_drawing(name)
    H, W = d.image.shape[:2]
    p = int(round(pad * max(H, W)))
    img = np.pad(d.image, ((p, p), (p, p), (0, 0)))
    mask = np.pad(d.notes["mask"], p)
    s = size / max(img.shape[:2])
    wh = (max(1, round(img.shape[1] * s)), max(1, round(img.shape[0] * s)))
    small = np.asarray(Image.fromarray(img).resize(wh, Image.LANCZOS))
    m = np.asarray(Image.fromarray(mask.astype(np.uint8) * 255).resize(wh, Image.BILINEAR)) > 127
    sk = Skeleton(**d.notes["skeleton"])
    return small, m, sk.with_xy((sk.xy + p + 0.5) * s - 0.5)  # pixel centres scale about -½


def _animated_drawing_pairs(size, n):
    """Windows as long as each :data:`AD_SHOTS` shot over the whole motion, every half shot,
    through the shot; the shot itself gets images (the drawing posed by :func:`pose_drawing`
    at the keys and at the true middle pose)."""
    from .retarget import ANIMATED_DRAWINGS_START_FRAMES, load_motion
    from .template import build_template

    out = []
    for name, (motion, t0, t1) in AD_SHOTS.items():
        img, mask, sk = _scaled_drawing(name, size)
        bvh = load_motion(motion)
        ref = ANIMATED_DRAWINGS_START_FRAMES[motion]
        span, shot = (t1 - t0) * bvh.fps, t0 * bvh.fps
        starts = _window_starts(float(ref), bvh.n_frames - 1, span, anchor=shot)
        windows = _posed_windows(bvh, sk, starts, span, n, reference_frame=ref)

        def images(truth, img=img, mask=mask, sk=sk):
            rest = build_template(img, sk, mask=mask)
            return tuple(pose_drawing(rest, truth[i])[0] for i in (0, -1, len(truth) // 2))

        for f0, truth in zip(starts, windows):
            out.append(InterpolationPair(f"{name}/{motion}@{f0:.0f}", "animated_drawings", truth,
                                         partial(images, truth) if f0 == shot else None))
    return out


def interpolation_pairs(sources=INTERPOLATION_SOURCES, size=256, n_frames=7, gap=0.4):
    """Key pairs whose true in-between skeletons are known, to compare interpolation schemes.

    Sources (:data:`INTERPOLATION_SOURCES`):

    * ``"procedural"`` — :func:`~physlab.inbetween.characters.inbetween_benchmark`; its truth
      *is* ``interpolate(..., method="local_angles")``, so that method is exact here;
    * ``"mocap"`` — the procedural character posed by the Bandai-Namco clips
      :data:`MOCAP_CLIPS` (:data:`CHARACTER_BANDAI_MAPPING`, root moved with the Hips),
      key pairs ``gap`` seconds apart every ``gap / 2``; one image pair per clip;
    * ``"animated_drawings"`` — the AnimatedDrawings characters scaled to ``size`` posed by
      their :data:`AD_SHOTS` motions (:func:`~physlab.inbetween.retarget.bvh_to_skeletons`),
      key pairs as long as the shot every half shot; the shot itself is the image pair.

    Both real sources need ``../shared/data`` (see :func:`physlab.datasets.external_data_dir`).

    Parameters
    ----------
    sources : iterable of names in :data:`INTERPOLATION_SOURCES`.
    size : int, image size in px (the procedural figure is 70 % of it tall; a drawing with
        its padding fills it).
    n_frames : odd int ≥ 3, skeletons per pair including both keys (the middle one is t = ½).
    gap : float > 0, seconds between the keys of the ``"mocap"`` pairs.

    Returns
    -------
    list of :class:`InterpolationPair`.
    """
    bad = [s for s in sources if s not in INTERPOLATION_SOURCES]
    if bad:
        raise ValueError(f"unknown interpolation source(s) {bad}; choose from "
                         f"{INTERPOLATION_SOURCES}")
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)) \
            or n_frames < 3 or n_frames % 2 == 0:
        raise ValueError(f"n_frames must be an odd int ≥ 3 (the middle frame is t = 0.5), got "
                         f"{n_frames!r}")
    if not gap > 0:
        raise ValueError(f"gap must be > 0 seconds, got {gap}")
    make = {"procedural": lambda: _procedural_pairs(size, n_frames),
            "mocap": lambda: _mocap_pairs(size, n_frames, gap),
            "animated_drawings": lambda: _animated_drawing_pairs(size, n_frames)}
    return [p for s in sources for p in make[s]()]


def interpolation_errors(pairs, methods=INTERPOLATION_METHODS):
    """Joint errors (px) of every interpolation method against the true skeletons.

    Returns
    -------
    list of dicts (pair, source, method, ``mid_mean`` / ``mid_worst``: mean and largest joint
    distance at t = ½; ``all_mean``: mean over the in-betweens and joints; ``all_worst``:
    largest joint distance per in-between, averaged over the in-betweens).
    """
    rows = []
    for pair in pairs:
        truth = pair.truth
        n = len(truth)
        X = np.stack([s.xy for s in truth])                              # (n, J, 2)
        for m in methods:
            Y = np.stack([s.xy for s in interpolate(truth[0], truth[-1],
                                                     np.linspace(0.0, 1.0, n), method=m)])
            e = np.linalg.norm(Y - X, axis=-1)[1:-1]                       # (n - 2, J)
            mid = e[n // 2 - 1]
            rows.append({"pair": pair.name, "source": pair.source, "method": m,
                         "mid_mean": float(mid.mean()), "mid_worst": float(mid.max()),
                         "all_mean": float(e.mean()), "all_worst": float(e.max(axis=1).mean())})
    return rows


def interpolation_psnr(pairs, methods=INTERPOLATION_METHODS, progress=True, interpolator=None,
                       **options):
    """PSNR (dB) at t = ½ of :func:`~physlab.inbetween.pipeline.inbetween` driven by each
    method's animation, on the pairs that have images.

    Also the references :data:`INTERPOLATION_REFERENCES`: the true animation passed as
    ``animation=``, and the cross-dissolve.

    Parameters
    ----------
    pairs : :class:`InterpolationPair` s (those without ``images`` are skipped).
    methods : names in :data:`INTERPOLATION_METHODS`.
    progress : bool, a tqdm bar over the pairs.
    interpolator : FrameInterpolator shared by all runs (default ``FlowInterpolator()``).
    options : passed to ``inbetween``.

    Returns
    -------
    list of dicts (pair, source, method, psnr, seconds).
    """
    import warnings

    pairs = [p for p in pairs if p.images is not None]
    interp = FlowInterpolator() if interpolator is None else interpolator
    it = pairs
    if progress:
        from tqdm.auto import tqdm

        it = tqdm(pairs, desc="in-betweens")
    rows = []
    for pair in it:
        k0, k1, gt = pair.images()
        truth, n = pair.truth, len(pair.truth)
        anims = {m: interpolate(truth[0], truth[-1], np.linspace(0.0, 1.0, n), method=m)
                 for m in methods}
        anims["true_animation"] = truth
        for m, anim in anims.items():
            tic = time.perf_counter()
            with warnings.catch_warnings():  # limb-overlap warnings: every method alike
                warnings.simplefilter("ignore")
                res = inbetween(k0, k1, truth[0], truth[-1], n, animation=anim,
                                interpolator=interp, **options)
            rows.append({"pair": pair.name, "source": pair.source, "method": m,
                         "psnr": metrics.psnr(res.frames[n // 2], gt),
                         "seconds": time.perf_counter() - tic})
        mid = cross_dissolve(as_rgba_float(k0, "key0"), as_rgba_float(k1, "key1"), n)[n // 2]
        rows.append({"pair": pair.name, "source": pair.source, "method": "cross_dissolve",
                     "psnr": metrics.psnr(mid, gt), "seconds": 0.0})
    return rows


def interpolation_table(errors, psnr=()):
    """Plain-text table of :func:`interpolation_errors` and :func:`interpolation_psnr` rows:
    per source and method, the pair count and mean joint errors (px), and the mean PSNR at
    t = ½ over the image pairs; the best method per source and column in *stars* (reference
    rows :data:`INTERPOLATION_REFERENCES` are not starred)."""
    cols = ("mid_mean", "mid_worst", "all_mean", "all_worst")
    head = ["source", "method", "pairs", "mid mean px", "mid worst px", "all mean px",
            "all worst px", "PSNR mid dB (pairs)"]
    lines = [" | ".join(head), " | ".join("---" for _ in head)]
    rows = list(errors) + list(psnr)
    for src in dict.fromkeys(r["source"] for r in rows):
        mine = [r for r in rows if r["source"] == src]
        methods = [m for m in dict.fromkeys(r["method"] for r in mine)
                   if m not in INTERPOLATION_REFERENCES]
        refs = [m for m in INTERPOLATION_REFERENCES if any(r["method"] == m for r in mine)]
        err = {m: [r for r in errors if r["source"] == src and r["method"] == m]
               for m in methods}
        cell = {(m, c): f"{np.mean([r[c] for r in err[m]]):.2f}"
                for m in methods if err[m] for c in cols}
        ps = {m: [r["psnr"] for r in psnr if r["source"] == src and r["method"] == m]
              for m in methods + refs}
        cell.update({(m, "psnr"): f"{np.mean(v):.2f}" for m, v in ps.items() if v})
        best = {}
        for c in cols + ("psnr",):
            vals = [cell[m, c] for m in methods if (m, c) in cell]
            if vals:
                best[c] = (max if c == "psnr" else min)(vals, key=float)
        for m in methods + refs:
            out = [src, m, str(len(err[m])) if err.get(m) else "—"]
            for c in cols + ("psnr",):
                v = cell.get((m, c))
                if v is None:
                    v = "0" if m == "true_animation" and c != "psnr" else "—"
                elif m in methods and v == best[c]:
                    v = f"*{v}*"
                out.append(f"{v} ({len(ps[m])})" if c == "psnr" and ps[m] else v)
            lines.append(" | ".join(out))
    return "\n".join(lines)


def compare_interpolation(sources=INTERPOLATION_SOURCES, size=256, n_frames=7, gap=0.4,
                          psnr=True, progress=True, methods=INTERPOLATION_METHODS, **options):
    """Compare the skeleton interpolation schemes of :func:`interpolate` (issue 15, point 3).

    Builds :func:`interpolation_pairs`, scores every method's skeletons
    (:func:`interpolation_errors`) and, with ``psnr``, the in-betweens they drive
    (:func:`interpolation_psnr`). Sources that need the external data folder are skipped, with
    the reason, when it is missing. Joint errors take seconds; the 28 image pairs × 8 rows
    of in-betweens about 10 minutes on a 2-core machine at 256 px (a few mocap pairs whose
    limbs cross the body take 20–45 s per in-between).

    Returns
    -------
    dict with "errors" and "psnr" (row lists), "table" (:func:`interpolation_table`),
    "skipped" (source → reason).
    """
    from ..datasets import external_data_dir

    skipped = {}
    if external_data_dir() is None:
        for s in sources:
            if s != "procedural":
                skipped[s] = ("external data folder not found (set PHYSLAB_EXTERNAL_DATA or "
                              "provide ../shared/data)")
    pairs = interpolation_pairs([s for s in sources if s not in skipped], size, n_frames, gap)
    errors = interpolation_errors(pairs, methods)
    ps = interpolation_psnr(pairs, methods, progress=progress, **options) if psnr else []
    return {"errors": errors, "psnr": ps, "table": interpolation_table(errors, ps),
            "skipped": skipped}


def _pairs_arg(text):
    """``--pairs``: a count N (the first N procedural pairs) or a pair folder (Path)."""
    import argparse

    if text.isdigit():
        if int(text) < 1:
            raise argparse.ArgumentTypeError(f"N must be >= 1, got {text} (or give a folder)")
        return int(text)
    return Path(text)


def _parser():
    from physlab._cli import Parser

    p = Parser(
        prog="python -m physlab.inbetween.evaluate",
        description="Ground-truth inbetweening benchmark (procedural cartoon characters), or "
                    "one's own keyframe pair (--pairs DIR): cross-dissolve, flow "
                    "interpolation, physlab (diagonal blend), physlab (blending "
                    "optimisation); PSNR, SSIM, Chamfer ×1e5 wherever ground truth exists.",
        epilog="examples:\n"
               "  %(prog)s --pairs 2 --size 256 --frames 5\n"
               "  %(prog)s --out runs/inbetween_eval\n"
               "  %(prog)s --real --skip-benchmark --out runs/real    # needs ../shared/data\n"
               "  %(prog)s --pairs my_pair/ --out runs/my_pair          # one's own triplet\n"
               "  %(prog)s --occluded --size 256 --out runs/occluded     # limbs crossing\n"
               "  %(prog)s --occluded --source animated_drawings --out runs/ad_occluded\n"
               "  %(prog)s --occluded --source animated_drawings --truth parts   # cut-out truth\n"
               "  %(prog)s --interpolation                  # skeleton interpolation methods\n"
               "\na --pairs DIR folder:\n" + FOLDER_FORMAT.replace("%", "%%"))
    p.add_argument("--size", type=int, default=None,
                   help="image size of the procedural pairs in px (default 512)")
    p.add_argument("--frames", type=int, default=None,
                   help="frames per pair including both keys (default 11 = 9 in-betweens; "
                        "for --pairs DIR the folder's rule below)")
    p.add_argument("--pairs", type=_pairs_arg, default=None, metavar="N|DIR",
                   help="N: evaluate only the first N procedural pairs; DIR: evaluate the "
                        "keyframe pair in folder DIR instead of the benchmark (layout below; "
                        "write ./2 for a folder named 2)")
    p.add_argument("--out", type=Path, default=None,
                   help="folder for the table (table.md), rows (rows.json) and contact sheets "
                        "(PNG); with --pairs DIR default DIR/evaluation")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument("--real", action="store_true",
                   help="also inbetween the six AnimatedDrawings characters posed by BVH "
                        "motions (needs ../shared/data); contact sheets go to --out")
    p.add_argument("--skip-benchmark", action="store_true",
                   help="skip the procedural ground-truth benchmark")
    p.add_argument("--interpolation", action="store_true",
                   help="compare the skeleton interpolation methods between keys "
                        f"({', '.join(INTERPOLATION_METHODS)}) against true in-between "
                        "poses: joint errors and the PSNR of the in-betweens they drive "
                        "(default --size 256 --frames 7; mocap and AnimatedDrawings pairs need "
                        "../shared/data)")
    p.add_argument("--gap", type=float, default=0.4,
                   help="--interpolation: seconds between the keys of the mocap pairs "
                        "(default 0.4)")
    p.add_argument("--no-psnr", action="store_true",
                   help="--interpolation: joint errors only, no in-betweens (seconds "
                        "instead of ~10 minutes)")
    p.add_argument("--occluded", action="store_true",
                   help="evaluate the occlusion benchmark instead (limbs crossing the body; "
                        "layered templates from the true occlusions, plus physlab as a single "
                        "sheet)")
    p.add_argument("--source", choices=("procedural", "animated_drawings"),
                   default="procedural",
                   help="--occluded: the procedural occlusion benchmark (default), or the "
                        "AnimatedDrawings characters posed by BVH motions whose hand crosses "
                        "the body (AD_OCCLUDED_SHOTS; occlusions suggested, not annotated; "
                        "default --size 256; needs ../shared/data, skipped without it)")
    p.add_argument("--no-t-junctions", action="store_true",
                   help="--occluded --source animated_drawings: suggested regions without "
                        "suggested T-junctions (the route before 2026-11-26)")
    p.add_argument("--rest-widths", action="store_true",
                   help="--occluded --source animated_drawings: suggested regions from capsules "
                        "as wide as each limb is drawn in the rest drawing (bone_widths) "
                        "instead of one radius for all bones")
    p.add_argument("--regions", choices=("capsule", "contact"), default=DEFAULT_REGIONS,
                   help="--occluded --source animated_drawings: suggested regions as capsule "
                        "overlaps, or grown to the limb's whole contact with the body "
                        f"(limb_contact; default {DEFAULT_REGIONS})")
    p.add_argument("--limb-up", action="store_true",
                   help="--regions contact: grow each limb's region along the whole limb, upper "
                        "arm included (suggest_occlusions(up=True))")
    p.add_argument("--by-limb", action="store_true",
                   help="--regions contact: put a region's limb handles on one layer, by bone "
                        "(suggest_occlusions(by_limb=True)), not by the largest depth gap")
    p.add_argument("--truth", choices=OCCLUDED_TRUTHS, default="sheet",
                   help="--occluded --source animated_drawings: the ground truth, 'sheet' (the "
                        "rest drawing deformed as one sheet into each pose, default) or "
                        "'parts' (cut into body parts moved rigidly, painted by depth)")
    p.add_argument("--texture-quality", choices=("inpainted", "none"), default="inpainted",
                   help="benchmark: the blending costs' texture quality q (Sec. 5.2) from the "
                        "visible inpainted pixels of the layered templates (default), or q ≡ 1 "
                        "(an ablation; no effect without occlusions)")
    return p


def _main_folder(args):
    """``--pairs DIR``: evaluate one's own pair, print the table, write the contact sheet."""
    if args.size is not None:
        raise ValueError(f"--size {args.size} sets the procedural pairs' size; a --pairs "
                         f"folder ({args.pairs}) has its keys' size: drop --size")
    out = args.pairs / "evaluation" if args.out is None else args.out
    r = evaluate_folder(args.pairs, n_frames=args.frames, out=out,
                        progress=not args.no_progress)
    res, n = r["result"], r["n_frames"]
    print(f"{args.pairs}: {n} frames (keys included), {res.frames.shape[2]}x"
          f"{res.frames.shape[1]} px")
    if r["table"]:
        print(r["table"])
        print("\nCD = Chamfer distance between dark pixels ×1e5.")
    else:
        print("no ground truth (gt_<t>.png) in the folder: no metrics; compare the methods "
              "on the contact sheet")
    occ = r["occlusions"]
    if any(o is not None for o in occ):
        print("occlusion regions: " + ", ".join(f"key{k} {0 if o is None else len(o)}"
                                                for k, o in enumerate(occ))
              + " (layered templates)")
    print(f"physlab: {r['seconds']['physlab']:.1f} s, largest handle error "
          f"{res.handle_error.max():.2f} px, {int(res.flipped.sum())} flipped triangles")
    flagged = {i: f for i, f in enumerate(res.flags) if f}
    if flagged:
        print("quality flags: " + "; ".join(f"frame {i}: {', '.join(f)}"
                                            for i, f in flagged.items()))
    print("wrote " + ", ".join(str(f) for f in r["files"]))


def _main_occluded_drawings(args, n_frames):
    """``--occluded --source animated_drawings``: print and write the real-drawing tables."""
    from ..datasets import ANIMATED_DRAWINGS_ATTRIBUTION

    shots = AD_OCCLUDED_SHOTS
    if args.pairs is not None:
        shots = dict(list(shots.items())[:args.pairs])
    r = evaluate_occluded_drawings(shots, size=256 if args.size is None else args.size,
                                   n_frames=n_frames, out=args.out,
                                   progress=not args.no_progress,
                                   texture_quality=args.texture_quality,
                                   t_junctions=not args.no_t_junctions,
                                   rest_widths=args.rest_widths, truth=args.truth,
                                   regions=args.regions, up=args.limb_up,
                                   by_limb=args.by_limb)
    if r["skipped"]:
        print(f"skipped AnimatedDrawings occlusions: {r['skipped']}")
        return
    print(r["table"])
    print()
    print(r["physlab"])
    print(f"\nCD = Chamfer distance between dark pixels ×1e5. Occlusions suggested by "
          f"suggest_occlusions, T-junctions "
          f"{'none' if args.no_t_junctions else 'suggested'}, regions {args.regions}"
          f"{' (whole limb)' if args.limb_up else ''}"
          f"{', limb handles on one layer' if args.by_limb else ''}, "
          f"capsule radii "
          f"{'the limbs drawn half-widths' if args.rest_widths else 'one for all bones'}"
          f", joint depths from the BVH. Ground truth: "
          f"{'the drawing cut into rigid parts' if args.truth == 'parts' else 'one sheet'}. "
          f"{ANIMATED_DRAWINGS_ATTRIBUTION}")
    if r["files"]:
        print("wrote " + ", ".join(str(f) for f in r["files"]))


def _main_interpolation(args):
    """``--interpolation``: print (and with ``--out`` write) the interpolation table."""
    import json

    from .._io import atomic_write_text

    r = compare_interpolation(size=256 if args.size is None else args.size,
                              n_frames=7 if args.frames is None else args.frames, gap=args.gap,
                              psnr=not args.no_psnr, progress=not args.no_progress)
    for src, why in r["skipped"].items():
        print(f"skipped {src}: {why}")
    print(r["table"])
    print("\nJoint errors (px) of the interpolated skeletons against the true ones: at t = 0.5 "
          "(mean over joints, worst joint) and over all in-betweens; PSNR of the physlab "
          "in-between at t = 0.5. mocap: Bandai-Namco clips (CC BY-NC 4.0, © 2022 Bandai Namco "
          "Research Inc.); animated_drawings: AnimatedDrawings (MIT, © Meta Platforms, Inc.).")
    if args.out is not None:
        atomic_write_text(args.out / "interpolation.md", r["table"] + "\n")
        atomic_write_text(args.out / "interpolation_rows.json",
                          json.dumps({"errors": r["errors"], "psnr": r["psnr"]}, indent=1))
        print(f"wrote {args.out / 'interpolation.md'} and interpolation_rows.json")
    return 0


def main(argv=None):
    """Command-line entry point; prints the table(s) and returns 0."""
    args = _parser().parse_args(argv)
    import json

    from .._io import atomic_write_text

    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
    if args.interpolation:
        return _main_interpolation(args)
    n_frames = DEFAULT_FRAMES if args.frames is None else args.frames
    if args.source != "procedural" and not args.occluded:
        raise ValueError(f"--source {args.source} is for --occluded; add --occluded")
    if args.truth != "sheet" and not (args.occluded and args.source == "animated_drawings"):
        raise ValueError(f"--truth {args.truth} is for --occluded --source animated_drawings; "
                         "add them")
    if args.regions != DEFAULT_REGIONS and not (args.occluded and
                                                args.source == "animated_drawings"):
        raise ValueError(f"--regions {args.regions} is for --occluded --source "
                         "animated_drawings (the procedural pairs use their true regions); "
                         "add them")
    for flag, on in (("--limb-up", args.limb_up), ("--by-limb", args.by_limb)):
        if on and not (args.occluded and args.source == "animated_drawings"
                       and args.regions == "contact"):
            raise ValueError(f"{flag} is for --occluded --source animated_drawings --regions "
                             "contact; add them")
    if isinstance(args.pairs, Path):
        _main_folder(args)
    elif args.occluded and args.source == "animated_drawings":
        _main_occluded_drawings(args, n_frames)
    elif not args.skip_benchmark:
        from .characters import inbetween_benchmark, occlusion_benchmark

        bench = occlusion_benchmark if args.occluded else inbetween_benchmark
        pairs = bench(size=512 if args.size is None else args.size)
        if args.pairs is not None:
            pairs = pairs[:args.pairs]
        rows = evaluate_pairs(pairs, n_frames=n_frames, progress=not args.no_progress,
                              sheets=None if args.out is None else args.out / "pairs",
                              texture_quality=args.texture_quality)
        table = format_table(summarize(rows))
        print(table)
        ok, why = metrics.lpips_status()
        print(f"\nCD = Chamfer distance between dark pixels ×1e5. LPIPS "
              f"{'available: ' if ok else 'not computed: '}{why}")
        if args.out is not None:
            atomic_write_text(args.out / "table.md", table + "\n")
            atomic_write_text(args.out / "rows.json", json.dumps(rows, indent=1))
            print(f"wrote {args.out / 'table.md'} and rows.json")
    if args.real:
        from ..datasets import ANIMATED_DRAWINGS, ANIMATED_DRAWINGS_ATTRIBUTION
        from .plots import contact_sheet

        print(f"\nReal drawings ({ANIMATED_DRAWINGS_ATTRIBUTION}):")
        print("character | motion | BVH frames | flipped triangles | max handle error (px) | s")
        for name in ANIMATED_DRAWINGS:
            r = animated_drawing_inbetween(name, n_frames=n_frames,
                                           progress=not args.no_progress)
            fr = r["frames"]
            print(f"{name} | {r['motion']} | {fr[0]:.0f}–{fr[-1]:.0f} | {r['flipped']} | "
                  f"{r['max_handle_error_px']:.3f} | {r['seconds']:.1f}")
            if args.out is not None:
                res = r["result"]
                labels = ["key 0"] + [f"α={a:.2f}" for a in res.path.alphas[1:-1]] + ["key 1"]
                contact_sheet(res.frames, args.out / f"{name}_contact.png",
                              skeletons=r["skeletons"], labels=labels,
                              title=f"{name} · {r['motion']} · AnimatedDrawings (MIT, © Meta)")
    return 0


if __name__ == "__main__":
    from physlab._cli import guard

    sys.exit(guard("python -m physlab.inbetween.evaluate", main))
