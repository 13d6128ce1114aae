"""Demos for lesson 11: storyboards become one animation (Zhong et al. 2025, "Sketch2Anim",
Sec. 6 "Motion Blending", Sec. 7.4, supp. D, Figs. 11 and 13, Table A4).

The storyboard, the placement, the blending methods and the 3D editing live in
:mod:`physlab.motion` (``storyboard``, ``blend``, ``transitions``, ``editing``); this module
draws the lesson's figures and computes its small tables. Joints are ``(T, 22, 3)`` metres,
y up, 20 fps.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from physlab.motion.blend import TRANSITION, blend, junction_step_ratio, place_after
from physlab.motion.metrics import bone_length_variation, floor_penetration, jerk, jerk_curve
from physlab.viz.plots import new_figure

__all__ = ["EXAMPLE_STORYBOARD", "FAST", "two_clips", "join_methods", "step_curve",
           "junction_figure", "blend_demo", "lesson_blending_table", "format_rows",
           "impact_figure", "METHOD_COLORS"]

DATA = Path(__file__).resolve().parents[2] / "data" / "motion"
#: A three-frame storyboard: a drawn walk (lesson 10's sketch), a bow, a wave.
EXAMPLE_STORYBOARD = DATA / "example_storyboard.json"
#: Generation options that keep the lesson fast (20 DDIM steps; the default guidance).
FAST = {"steps": 20}
FIG_DPI = 80
METHOD_COLORS = {"concat": "#d62728", "linear": "#7f7f7f", "slerp": "#9467bd",
                 "squad": "#ff7f0e", "inversion": "#1f77b4", "real": "#000000"}


def two_clips(first="a person walks", second="a person bows", seed=0, generator=None,
              **options):
    """Two generated clips of different actions, each in its own canonical frame:
    ``(a, b, (first, second))``."""
    from physlab.motion.sampling import load_generator

    gen = generator if generator is not None else load_generator()
    opts = {**FAST, **options}
    return gen(first, seed=seed, **opts), gen(second, seed=seed + 1, **opts), (first, second)


def join_methods(a, b, actions, methods=("concat", "linear", "squad", "inversion"),
                 transition=TRANSITION, generator=None, seed=0):
    """``{method: BlendResult}``: ``b`` placed after ``a`` (:func:`~physlab.motion.blend.
    place_after`) and joined by each method; plus ``"clips"``: the two placed clips per
    method (the cut places ``b`` right after ``a``)."""
    out = {}
    for m in methods:
        gap = 0 if m == "concat" else transition
        placed = place_after(a, b, gap)
        res = blend(a, placed, transition=gap, method=m, actions=actions, generator=generator,
                    seed=seed)
        res.clips = (a, placed)
        out[m] = res
    return out


def step_curve(joints):
    """(T-1,) largest joint step of every frame (m/frame): what "pops" at a seam."""
    x = np.asarray(joints, dtype=float)
    return np.linalg.norm(np.diff(x, axis=0), axis=-1).max(axis=-1)


def junction_figure(results, margin=15):
    """Largest joint step and jerk around the junction for each method (aligned on the
    first frame after the first clip; the transition shaded)."""
    fig, (ax0, ax1) = new_figure(2, 1, width=4.2, height=2.6)
    fig.set_dpi(FIG_DPI)
    l = 0
    for m, res in results.items():
        n_a = res.transition.start
        l = max(l, res.transition.stop - res.transition.start)
        lo = n_a - margin
        hi = min(len(res.joints), res.transition.stop + margin)
        k = np.arange(lo, hi - 1) - n_a
        ax0.plot(k + 0.5, step_curve(res.joints[lo:hi]), color=METHOD_COLORS.get(m), lw=1.4,
                 label=m)
        kj = np.arange(lo, hi - 3) - n_a
        ax1.plot(kj + 1.5, jerk_curve(res.joints[lo:hi]), color=METHOD_COLORS.get(m), lw=1.4,
                 label=m)
    for ax in (ax0, ax1):
        ax.axvspan(0, l, color="0.9", zorder=0)
        ax.set_xlabel("frame after the end of clip 1")
        ax.tick_params(labelsize=7)
    ax0.set_ylabel("largest joint step (m/frame)", fontsize=8)
    ax1.set_ylabel("jerk (m/frame³)", fontsize=8)
    ax1.set_yscale("log")
    ax1.set_ylim(bottom=1e-4)             # a straight-line blend has no jerk at all: clip it
    ax0.set_title("steps: a cut pops", fontsize=9)
    ax1.set_title("jerk around the junction (grey: transition)", fontsize=9)
    ax0.legend(fontsize=7, frameon=False)
    return fig


def blend_demo(method="inversion", transition=TRANSITION, second="a person bows", seed=0):
    """Widget callback: a walk joined to ``second`` by ``method`` with ``transition``
    frames; the motion from the side (pelvis height and forward travel, stick figures every
    5 frames, the transition in grey) and its step curve. Returns a Figure."""
    from physlab.motion.sampling import load_generator

    gen = load_generator()
    a, b, actions = two_clips(second=second, seed=seed, generator=gen)
    res = join_methods(a, b, actions, (method,), int(transition), generator=gen,
                       seed=seed)[method]
    x = res.joints
    fig, (ax0, ax1) = new_figure(2, 1, width=4.2, height=2.6, )
    fig.set_dpi(FIG_DPI)
    from physlab.motion.skeleton import PARENTS

    heading = x[-1, 0, [0, 2]] - x[0, 0, [0, 2]]
    d = heading / max(np.linalg.norm(heading), 1e-9)                 # forward direction
    s = x[..., 0] * d[0] + x[..., 2] * d[1]                           # (T, 22) along d
    for k in range(0, len(x), 5):
        in_gap = res.transition.start <= k < res.transition.stop
        c = "0.55" if in_gap else ("#1f77b4" if k < res.transition.start else "#2ca02c")
        for j in range(1, 22):
            ax0.plot(s[k, [PARENTS[j], j]], x[k, [PARENTS[j], j], 1], color=c, lw=0.9)
    ax0.set_aspect("equal")
    ax0.set_xlabel("forward (m)")
    ax0.set_ylabel("height (m)")
    ax0.set_title(f"walk → {second.removeprefix('a person ')} ({method}, {transition} frames)",
                  fontsize=9)
    ax1.plot(np.arange(len(x) - 1) + 0.5, step_curve(x), color=METHOD_COLORS.get(method))
    ax1.axvspan(res.transition.start, max(res.transition.stop, res.transition.start + 0.5),
                color="0.9", zorder=0)
    ratio = junction_step_ratio(x, res.window if res.window.stop > res.window.start else
                                res.transition, list(res.clips))
    ax1.set_title(f"largest joint step; junction / median = {ratio:.1f}", fontsize=9)
    ax1.set_xlabel("frame")
    ax1.set_ylabel("m / frame")
    for ax in (ax0, ax1):
        ax.tick_params(labelsize=7)
    return fig


def lesson_blending_table(methods=("linear", "slerp", "squad", "inpaint", "inversion"),
                          transition=TRANSITION, generator=None, seed=0):
    """A small Table A4 on the six held-out windows shipped with the lessons
    (``data/motion/lesson_windows.npz``): the middle ``transition`` frames masked and filled
    by each method. No FID (it needs more windows: ``python -m physlab.motion.evaluate
    --blending``); window ``i`` is filled with seed ``seed + i`` (the ``"inpaint"`` baseline's
    noise). Returns ``{row: {AUJ, PJ, MPJPE, bones, floor}}`` with a ``"real"`` row."""
    from physlab.demos.sketch_to_motion import lesson_window

    gt = np.stack([lesson_window(k)[0] for k in range(6)])
    texts = [lesson_window(k)[1] for k in range(6)]
    T = gt.shape[1]
    if isinstance(transition, bool) or not isinstance(transition, (int, np.integer)) \
            or not 1 <= transition <= T - 6:
        raise ValueError(f"transition must be an integer in 1..{T - 6} (3 context frames a "
                         f"side for the jerk), got {transition!r}")
    ca = (T - transition) // 2
    lo, hi = ca - 2, ca + transition + 2

    def row(x):
        auj, pj = jerk(x[:, lo:hi])
        err = np.linalg.norm(x[:, ca:ca + transition] - gt[:, ca:ca + transition], axis=-1)
        return {"AUJ": auj, "PJ": pj, "MPJPE": float(err.mean()),
                "bones": float(np.max(bone_length_variation(x))),
                "floor": float(np.mean(floor_penetration(x)))}

    rows = {"real": row(gt)}
    for m in methods:
        filled = np.stack([blend(g[:ca], g[ca + transition:], transition, m,
                                 actions=(t, t), generator=generator, seed=seed + i).joints
                           for i, (g, t) in enumerate(zip(gt, texts))])
        rows[m] = row(filled)
    return rows


def format_rows(rows):
    """Markdown table of :func:`lesson_blending_table`."""
    lines = ["| method | AUJ ↓ | PJ (real = {:.4f}) | MPJPE (m) | bone var (m) | floor % |"
             .format(rows["real"]["PJ"]), "|---|---|---|---|---|---|"]
    for m, r in rows.items():
        lines.append(f"| {m} | {r['AUJ']:.3f} | {r['PJ']:.4f} | {r['MPJPE']:.3f} | "
                     f"{r['bones']:.4f} | {100 * r['floor']:.1f} |")
    return "\n".join(lines)


def impact_figure(sequence):
    """Fig. 13: the pelvis paths seen from above and the last pose of each step of
    :func:`physlab.motion.editing.impact_of_conditions`."""
    from physlab.motion.skeleton import PARENTS

    fig, axes = new_figure(len(sequence), 1, width=2.3, height=2.6)
    fig.set_dpi(FIG_DPI)
    for ax, (label, x, cond) in zip(axes, sequence):
        for k in range(0, 40, 6):
            for j in range(1, 22):
                ax.plot(x[k, [PARENTS[j], j], 0], x[k, [PARENTS[j], j], 2],
                        color=(0.12, 0.47, 0.71, 0.25 + 0.6 * k / 40), lw=0.8)
        ax.plot(x[:, 0, 0], x[:, 0, 2], color="#1f77b4", lw=1.5, label="pelvis")
        if "trajectories_3d" in cond:
            p = cond["trajectories_3d"]["pelvis"]
            ax.plot(p[:, 0], p[:, 2], "g--", lw=1.2, label="condition")
        if "keypose_3d" in cond:
            kp = cond["keypose_3d"]
            ax.plot(kp[:, 0], kp[:, 2], "r.", ms=3, label="keypose")
        ax.set_title(label, fontsize=8)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x (m)", fontsize=7)
        ax.tick_params(labelsize=6)
    axes[0].set_ylabel("z, forward (m)", fontsize=7)
    axes[-1].legend(fontsize=6, frameon=False, loc="best")
    return fig
