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

Run ``python -m physlab.inbetween.evaluate --help``.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from . import metrics
from .baselines import cross_dissolve, flow_interpolation
from .blend import render_path
from .frame_interpolation import FlowInterpolator
from .pipeline import inbetween

__all__ = ["METHODS", "METRICS", "run_methods", "score_frames", "evaluate_pairs",
           "summarize", "format_table", "AD_SHOTS", "pose_drawing", "animated_drawing_inbetween",
           "main"]

METHODS = ("cross_dissolve", "flow", "physlab_diagonal", "physlab")
METRICS = ("psnr", "ssim", "cd")
#: larger is better for these metrics (the rest: smaller is better)
HIGHER_IS_BETTER = {"psnr": True, "ssim": True, "cd": False}


def run_methods(key0, key1, skeleton0, skeleton1, n_frames, animation=None, interpolator=None,
                **options):
    """Frames of every method in :data:`METHODS` for one keyframe pair.

    Returns
    -------
    frames : dict method → (n_frames, H, W, C) float32 (keys at both ends).
    result : the :class:`~physlab.inbetween.pipeline.InbetweenResult` of the physlab run.
    seconds : dict method → wall time.
    """
    interp = FlowInterpolator() if interpolator is None else interpolator
    frames, seconds = {}, {}
    tic = time.perf_counter()
    frames["cross_dissolve"] = cross_dissolve(key0, key1, n_frames)
    seconds["cross_dissolve"] = time.perf_counter() - tic
    tic = time.perf_counter()
    frames["flow"] = flow_interpolation(key0, key1, n_frames, interp)
    seconds["flow"] = time.perf_counter() - tic
    tic = time.perf_counter()
    res = inbetween(key0, key1, skeleton0, skeleton1, n_frames, animation=animation,
                    interpolator=interp, **options)
    seconds["physlab"] = time.perf_counter() - tic
    frames["physlab"] = res.frames
    tic = time.perf_counter()
    diag = np.asarray(render_path(res.fwd, res.bwd, res.diagonal, interp), np.float32)
    diag[0], diag[-1] = res.frames[0], res.frames[-1]
    frames["physlab_diagonal"] = diag[..., :res.frames.shape[-1]]
    seconds["physlab_diagonal"] = seconds["physlab"] + time.perf_counter() - tic
    return frames, res, seconds


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
    per = {"psnr": [], "ssim": [], "cd": []}
    for f, g in zip(frames[1:-1], truth[1:-1]):
        per["psnr"].append(metrics.psnr(f, g))
        per["ssim"].append(metrics.ssim(f, g))
        per["cd"].append(metrics.chamfer(f, g, scale=metrics.CD_SCALE))
    mid = n // 2 - 1
    out = {}
    for k, v in per.items():
        out[f"{k}_mid"] = float(v[mid])
        out[f"{k}_all"] = float(np.mean(v))
    return out


def comparison_sheet(frames, truth, path=None, every=2, title=None):
    """Figure: ground truth and every method (rows) over time (every ``every``-th frame)."""
    from .plots import over_white
    from ..viz.plots import new_figure

    idx = list(range(0, len(truth), every))
    if idx[-1] != len(truth) - 1:
        idx.append(len(truth) - 1)
    rows = [("ground truth", truth)] + [(m, frames[m]) for m in METHODS]
    H, W = np.asarray(truth[0]).shape[:2]
    fig, axes = new_figure(ncols=len(idx), nrows=len(rows), width=1.0, height=1.0 * H / W)
    axes = np.asarray(axes).reshape(len(rows), len(idx))
    n = len(truth)
    for r, (name, seq) in enumerate(rows):
        for c, i in enumerate(idx):
            ax = axes[r, c]
            ax.imshow(over_white(seq[i]))
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


def evaluate_pairs(pairs, n_frames=11, progress=True, interpolator=None, sheets=None,
                   **options):
    """Score every method on every benchmark pair.

    Parameters
    ----------
    pairs : iterable of pairs with ``name``, ``kind`` ("tight"/"far"), ``keyframes()``,
        ``skeleton0``, ``skeleton1``, ``animation(n)`` and ``ground_truth(t)``
        (:class:`physlab.inbetween.characters.InbetweenPair`).
    n_frames : int, frames per pair including both keys (9 in-betweens → 11).
    sheets : folder for a :func:`comparison_sheet` PNG per pair, or None.
    options : passed to :func:`~physlab.inbetween.pipeline.inbetween`.

    Returns
    -------
    rows : list of dicts (pair, kind, method, seconds, metric values, and for "physlab" the
        largest handle error and flipped-triangle count).
    """
    pairs = list(pairs)
    it = pairs
    if progress:
        from tqdm.auto import tqdm

        it = tqdm(pairs, desc="pairs")
    rows = []
    t = np.linspace(0.0, 1.0, n_frames)
    for pair in it:
        key0, key1 = pair.keyframes()
        truth = np.asarray(pair.ground_truth(t))
        frames, res, sec = run_methods(key0, key1, pair.skeleton0, pair.skeleton1, n_frames,
                                       animation=pair.animation(n_frames),
                                       interpolator=interpolator, **options)
        if sheets is not None:
            comparison_sheet(frames, truth, Path(sheets) / f"{pair.name}.png",
                             title=f"{pair.name} ({pair.kind}, {getattr(pair, 'style', '')})")
        for m in METHODS:
            row = {"pair": pair.name, "kind": pair.kind, "method": m, "seconds": sec[m]}
            row.update(score_frames(frames[m], truth))
            if m.startswith("physlab"):
                row["handle_error_px"] = float(res.handle_error.max())
                row["flipped"] = int(res.flipped.sum())
            rows.append(row)
    return rows


def summarize(rows):
    """Mean of every metric per (kind, method): dict ``(kind, method) → {metric: mean}``.

    ``kind`` "all" pools every pair.
    """
    out = {}
    kinds = sorted({r["kind"] for r in rows}) + ["all"]
    keys = [f"{m}_{w}" for m in METRICS for w in ("mid", "all")]
    for kind in kinds:
        for m in METHODS:
            sel = [r for r in rows if r["method"] == m and kind in (r["kind"], "all")]
            if sel:
                out[kind, m] = {k: float(np.mean([r[k] for r in sel])) for k in keys}
                out[kind, m]["n"] = len(sel)
    return out


def format_table(summary):
    """Plain-text table of :func:`summarize` (best value per column and group in *stars*)."""
    cols = [f"{m}_{w}" for w in ("mid", "all") for m in METRICS]
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


def _parser():
    from physlab._cli import Parser

    p = Parser(
        prog="python -m physlab.inbetween.evaluate",
        description="Ground-truth inbetweening benchmark (procedural cartoon characters): "
                    "cross-dissolve, flow interpolation, physlab (diagonal blend), physlab "
                    "(blending optimisation); PSNR, SSIM, Chamfer ×1e5.",
        epilog="examples:\n"
               "  %(prog)s --pairs 2 --size 256 --frames 5\n"
               "  %(prog)s --out runs/inbetween_eval\n"
               "  %(prog)s --real --skip-benchmark --out runs/real    # needs ../shared/data")
    p.add_argument("--size", type=int, default=512, help="image size in px (default 512)")
    p.add_argument("--frames", type=int, default=11,
                   help="frames per pair including both keys (default 11 = 9 in-betweens)")
    p.add_argument("--pairs", type=int, default=None, help="evaluate only the first N pairs")
    p.add_argument("--out", type=Path, default=None,
                   help="folder for the table (table.md), per-pair rows (rows.json) and "
                        "contact sheets (PNG)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument("--real", action="store_true",
                   help="also inbetween the six AnimatedDrawings characters posed by BVH "
                        "motions (needs ../shared/data); contact sheets go to --out")
    p.add_argument("--skip-benchmark", action="store_true",
                   help="skip the procedural ground-truth benchmark")
    return p


def main(argv=None):
    """Command-line entry point; prints the table and returns 0 if physlab wins on far pairs."""
    args = _parser().parse_args(argv)
    import json

    from .._io import atomic_write_text

    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
    if not args.skip_benchmark:
        from .characters import inbetween_benchmark

        pairs = inbetween_benchmark(size=args.size)
        if args.pairs is not None:
            pairs = pairs[:args.pairs]
        rows = evaluate_pairs(pairs, n_frames=args.frames, progress=not args.no_progress,
                              sheets=None if args.out is None else args.out / "pairs")
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
            r = animated_drawing_inbetween(name, n_frames=args.frames,
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
