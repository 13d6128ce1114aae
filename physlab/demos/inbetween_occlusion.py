"""Demos for lesson 07: occlusions and layered templates (Brodt & Bessmeltsev 2024,
"Skeleton-Driven Inbetweening of Bitmap Character Drawings", Secs. 3, 4.1–4.4, 5.1, Eq. 2,
Algorithm 1, Figs. 2d, 5–8).

``*_demo`` functions are widget callbacks (keyword parameters in, a Figure out); the
``*_figure`` functions draw the lesson's static figures. The algorithms live in
:mod:`physlab.inbetween.occlusion`; this module only wires them to plots.
"""
from __future__ import annotations

import matplotlib.colors
import numpy as np

from physlab.inbetween import characters
from physlab.inbetween.occlusion import (Occlusion, build_layered_template,
                                         count_valid_assignments, valid_assignments)
from physlab.inbetween.pipeline import deform_sequence
from physlab.inbetween.plots import draw_mesh, draw_skeleton, over_white
from physlab.inbetween.template import build_template
from physlab.viz.plots import new_figure

__all__ = ["occluded_pair", "tear_sequences", "tear_figure", "template_figure",
           "switching_rule_figure", "shifted_t_junctions", "t_junction_demo",
           "wrong_topology", "wrong_topology_figure",
           "comparison_figure", "three_layers", "three_layer_figure", "VISIBLE", "HIDDEN"]

#: Outline colours of Figs. 6 and 8: visible occlusion contours blue, hidden ones red.
VISIBLE, HIDDEN = "tab:blue", "tab:red"


def _grid(rows, cols, width, height):
    """(fig, axes (rows, cols)) with panels ``width`` × ``height`` inches."""
    fig, axes = new_figure(cols, rows, width=width, height=height)
    return fig, np.asarray(axes, dtype=object).reshape(rows, cols)


def occluded_pair(name="fold_arm", size=160):
    """A pair of :func:`~physlab.inbetween.characters.occlusion_benchmark` and its keys and
    true occlusions: ``(pair, key0, key1, occ0, occ1)``."""
    pairs = {p.name: p for p in characters.occlusion_benchmark(size)}
    if name not in pairs:
        raise ValueError(f"name must be one of {sorted(pairs)}, got {name!r}")
    p = pairs[name]
    k0, k1 = p.keyframes()
    o0, o1 = p.occlusions()
    return p, k0, k1, o0, o1


def _box(masks, margin=12):
    m = np.any(masks, axis=0)
    ys, xs = np.nonzero(m)
    return (max(xs.min() - margin, 0), xs.max() + margin, ys.max() + margin,
            max(ys.min() - margin, 0))


def tear_sequences(pair, key1, occ1, n=4):
    """Key 1's drawing deformed back towards key 0 by a single sheet and by the layered
    template: ``(times, single frames, layered frames, single E_d, layered E_d, templates)``."""
    anim = pair.animation(n)[::-1]                       # from key 1 to key 0
    single = build_template(key1, pair.skeleton1)
    layered = build_layered_template(key1, pair.skeleton1, occ1, target_skeletons=anim[1:],
                                     other_image=pair.keyframes()[0])
    xs, es, *_ = deform_sequence(single, anim)
    xl, el, *_ = deform_sequence(layered, anim)
    fs = [single.render(x) for x in xs]
    fl = [layered.render(x, skeleton=s) for x, s in zip(xl, anim)]
    return np.linspace(1, 0, n), fs, fl, es, el, (single, layered)


def tear_figure(pair, key1, occ1, n=4, sequences=None):
    """Fig. 2d analogue: a single sheet tears where a limb crossing the body moves away; the
    layered template does not. Rows: truth, single sheet, layered; E_d per frame.

    ``sequences``: what :func:`tear_sequences` returned for the same arguments, to draw it
    without solving the deformations again (default: solve them here).
    Returns ``(fig, (single, layered))`` (the two templates)."""
    if sequences is None:
        sequences = tear_sequences(pair, key1, occ1, n)
    t, fs, fl, es, el, tpls = sequences
    if len(t) != n:
        raise ValueError(f"sequences hold {len(t)} frames but n = {n}: pass what "
                         f"tear_sequences(pair, key1, occ1, n={n}) returned")
    truth = pair.ground_truth(t)
    fig, axes = _grid(3, n, 1.9, 2.0)
    for j in range(n):
        for i, (img, lab) in enumerate([(truth[j], "truth"),
                                         (fs[j], f"single sheet\nE_d = {es[j]:.2f}"),
                                         (fl[j], f"layered\nE_d = {el[j]:.2f}")]):
            ax = axes[i, j]
            ax.imshow(over_white(img))
            ax.set_xticks([])
            ax.set_yticks([])
            if j == 0:
                ax.set_ylabel(lab.split("\n")[0], fontsize=9)
            ax.set_title(f"t = {t[j]:.2f}" if i == 0 else lab.split("\n")[-1], fontsize=8)
    fig.suptitle("Key 1 deformed back to key 0 (E_d = 4 is rigid)", fontsize=10)
    return fig, tpls


def _draw_outline(ax, tpl, x=None):
    x = tpl.X if x is None else x
    for reg in tpl.regions:
        vis = reg.visible_edges()
        for i in range(reg.n_edges):
            a, b = reg.loop[i], reg.loop[(i + 1) % reg.n_edges]
            ax.plot(x[[a, b], 0], x[[a, b], 1], color=VISIBLE if vis[i] else HIDDEN, lw=3.0,
                    solid_capstyle="round")
        tj = x[reg.loop[reg.t_junctions]]
        ax.plot(tj[:, 0], tj[:, 1], "o", ms=6, mfc="yellow", mec="k", mew=0.8)


def template_figure(tpl):
    """The layered template (Figs. 5, 6): base mesh, the pocket layers over the occlusion
    region, the outline's visible (blue) and hidden (red) contours with the T-junctions
    (yellow), and the texture atlas: the keyframe for the base mesh and front layers, the
    back layer's texture (from the other key, else inpainted)."""
    H, W = tpl.shape
    box = _box([o.mask_array((H, W)) for o in tpl.occlusions], margin=30)
    fig, axes = _grid(1, 4, 2.9, 3.2)
    axes = axes[0]
    ax = axes[0]
    ax.imshow(over_white(tpl.image))
    draw_mesh(ax, tpl.X, tpl.tris, lw=0.25, color="0.35")
    draw_skeleton(ax, tpl.skeleton, lw=1.0, ms=2)
    ax.set_title(f"template: {tpl.mesh.n} vertices,\n{tpl.mesh.n_tris} triangles", fontsize=9)
    ax = axes[1]
    for reg in tpl.regions:
        front = reg.tris_a if reg.front == "A" else reg.tris_b
        back = reg.tris_b if reg.front == "A" else reg.tris_a
        draw_mesh(ax, tpl.X, tpl.tris[back], lw=0.6, color="tab:purple")
        draw_mesh(ax, tpl.X + np.array([3.0, -3.0]), tpl.tris[front], lw=0.6, color="tab:green")
    _draw_outline(ax, tpl)
    tight = _box([o.mask_array((H, W)) for o in tpl.occlusions], margin=6)
    ax.set_xlim(tight[0], tight[1])
    ax.set_ylim(tight[2], tight[3])
    ax.set_aspect(1, adjustable="box")
    ax.set_title("two layers in the region\n(front green, shifted; back purple)", fontsize=9)
    ax = axes[2]
    ax.imshow(over_white(tpl.image))
    _draw_outline(ax, tpl)
    ax.set_xlim(box[0], box[1])
    ax.set_ylim(box[2], box[3])
    ax.set_title("outline: visible (blue),\nhidden (red), T-junctions", fontsize=9)
    ax = axes[3]
    ax.imshow(over_white(tpl.texture[H:]))
    ax.set_xlim(box[0], box[1])
    ax.set_ylim(box[2], box[3])
    ax.set_title(f"back layer's texture\n({100 * tpl.inpainted_fraction:.0f} % inpainted)",
                 fontsize=9)
    for a in axes:
        a.set_xticks([])
        a.set_yticks([])
    return fig


def switching_rule_figure(n=12, t_junctions=(1, 5, 8), max_shown=8):
    """All assignments the switching rule (Eq. 2) allows on a closed outline of ``n`` edges with
    T-junctions at the given vertices: 2 for an even count, 2(n − k) for an odd one (one cusp,
    white cross). Edges with b = 1 are blue, b = 0 red."""
    cands = valid_assignments(n, t_junctions)
    k = len(t_junctions)
    shown = cands[:max_shown]
    ang = 2 * np.pi * np.arange(n) / n
    P = np.c_[np.cos(ang), np.sin(ang)]
    cols = min(len(shown), 4)
    rows = int(np.ceil(len(shown) / cols))
    fig, axes = _grid(rows, cols, 2.1, 2.2)
    for ax, (b, cusp) in zip(axes.ravel(), shown):
        for i in range(n):
            a, c = P[i], P[(i + 1) % n]
            ax.plot([a[0], c[0]], [a[1], c[1]], color=VISIBLE if b[i] else HIDDEN, lw=3)
        ax.plot(*P[list(t_junctions)].T, "o", ms=7, mfc="yellow", mec="k")
        if cusp is not None:
            ax.plot(*P[cusp], "x", ms=9, mew=2.5, color="k")
        ax.set_aspect(1)
        ax.axis("off")
        ax.set_title(f"cusp at {cusp}" if cusp is not None else "no cusp", fontsize=8)
    for ax in axes.ravel()[len(shown):]:
        ax.axis("off")
    fig.suptitle(f"n = {n} edges, k = {k} T-junctions: {len(cands)} valid assignments "
                 f"(formula {count_valid_assignments(n, k)})"
                 + (f", first {len(shown)} shown" if len(cands) > len(shown) else ""),
                 fontsize=9)
    return fig


def shifted_t_junctions(occlusion, shift):
    """The occlusion with every T-junction moved ``shift`` px along its region's outline
    (a deliberately wrong annotation, the Fig. 8 experiment)."""
    from physlab.mesh import boundary_polygon

    P = boundary_polygon(occlusion.mask_array(occlusion.mask.shape), epsilon=0.5)
    seg = np.linalg.norm(np.diff(np.r_[P, P[:1]], axis=0), axis=1)
    s = np.r_[0, np.cumsum(seg)]
    L = s[-1]
    out = []
    for q in occlusion.t_junctions:
        i = int(np.argmin(np.linalg.norm(P - q, axis=1)))
        target = (s[i] + shift) % L
        j = int(np.searchsorted(s, target, side="right") - 1) % len(P)
        f = (target - s[j]) / max(seg[j], 1e-9)
        out.append(P[j] + f * (P[(j + 1) % len(P)] - P[j]))
    return Occlusion(occlusion.mask, np.array(out), occlusion.label)


def t_junction_demo(shift=0.0, name="fold_arm", size=128):
    """Move the T-junctions along the outline, rebuild the template and see the assignments'
    energies (Eq. 1 at the far key), the chosen cut and the result at t = 0.5 against the
    truth (Figs. 6–8). ``shift`` in px."""
    from physlab.inbetween import metrics

    pair, k0, k1, o0, o1 = occluded_pair(name, size)
    occ = [shifted_t_junctions(o, shift) for o in o1]
    anim = pair.animation(5)[::-1]
    fig, axes = _grid(1, 3, 3.3, 3.2)
    axes = axes[0]
    try:
        tpl = build_layered_template(k1, pair.skeleton1, occ, target_skeletons=anim[1:],
                                     other_image=k0)
    except ValueError as err:
        for a in axes:
            a.axis("off")
        axes[1].text(0.5, 0.5, str(err), ha="center", va="center", wrap=True, fontsize=8)
        return fig
    x, *_ = deform_sequence(tpl, anim[:3])
    mid = tpl.render(x[2], skeleton=anim[2])
    truth = pair.ground_truth(0.5)
    box = _box([o.mask_array(tpl.shape) for o in occ], margin=24)
    axes[0].imshow(over_white(tpl.image))
    _draw_outline(axes[0], tpl)
    axes[0].set_xlim(box[0], box[1])
    axes[0].set_ylim(box[2], box[3])
    axes[0].set_title(f"T-junctions moved {shift:+.0f} px", fontsize=9)
    reg = tpl.regions[0]
    es = [e for _, _, e in reg.energies]
    chosen = [i for i, (b, _, _) in enumerate(reg.energies) if np.array_equal(b, reg.b)][0]
    axes[1].bar(range(len(es)), es, color=["tab:green" if i == chosen else "0.6"
                                           for i in range(len(es))])
    axes[1].set_yscale("log")
    axes[1].set_xlabel("valid assignment")
    axes[1].set_ylabel("E_d + E_pose at key 0")
    axes[1].set_title(f"{len(es)} assignments; chosen (green)", fontsize=9)
    p = metrics.psnr(mid, truth)
    axes[2].imshow(np.concatenate([over_white(mid), over_white(truth)], axis=1))
    axes[2].set_title(f"t = 0.5: template | truth ({p:.1f} dB)", fontsize=9)
    axes[2].set_xticks([])
    axes[2].set_yticks([])
    axes[0].set_xticks([])
    axes[0].set_yticks([])
    return fig


def wrong_topology(name="fold_arm", size=160, t=0.5):
    """The Fig. 8 experiment: key 1's template with the topology chosen by energy and with every
    other valid assignment of its region, each deformed to time ``t``; returns a list of
    ``(label, template, render, PSNR against the truth)``."""
    from physlab.inbetween import metrics

    pair, k0, k1, o0, o1 = occluded_pair(name, size)
    anim = pair.animation(5)[::-1]
    best = build_layered_template(k1, pair.skeleton1, o1, target_skeletons=anim[1:],
                                  other_image=k0)
    reg = best.regions[0]
    cands = valid_assignments(reg.n_edges, reg.t_junctions)
    chosen = [i for i, (b, _) in enumerate(cands) if np.array_equal(b, reg.b)][0]
    sk = pair.skeleton_at(t)
    truth = pair.ground_truth(t)
    out = []
    for i in [chosen] + [j for j in range(len(cands)) if j != chosen][:3]:
        tpl = best if i == chosen else build_layered_template(
            k1, pair.skeleton1, o1, target_skeletons=anim[1:], other_image=k0,
            assignments=[i])
        x, *_ = deform_sequence(tpl, [sk])          # from key 1's pose, with continuation
        img = tpl.render(x[0], skeleton=sk)
        out.append(("chosen by energy" if i == chosen else f"assignment {i}", tpl, img,
                    metrics.psnr(img, truth)))
    return out


def wrong_topology_figure(name="fold_arm", size=160, t=0.5):
    """Fig. 8 analogue: the outline's visible (blue) / hidden (red) contours of the chosen and
    of a wrong topology, and what each gives at time ``t`` (PSNR against the truth)."""
    rows = wrong_topology(name, size, t)
    fig, axes = _grid(2, len(rows), 2.6, 2.6)
    box = _box([o.mask_array(rows[0][1].shape) for o in rows[0][1].occlusions], margin=28)
    for j, (lab, tpl, img, p) in enumerate(rows):
        axes[0, j].imshow(over_white(tpl.image))
        _draw_outline(axes[0, j], tpl)
        axes[0, j].set_xlim(box[0], box[1])
        axes[0, j].set_ylim(box[2], box[3])
        axes[0, j].set_title(lab, fontsize=9)
        axes[1, j].imshow(over_white(img)[box[3]:box[2], box[0]:box[1]])
        axes[1, j].set_title(f"t = {t:g}: {p:.1f} dB", fontsize=9)
        for a in axes[:, j]:
            a.set_xticks([])
            a.set_yticks([])
    return fig


def comparison_figure(rows, truth, labels, t):
    """In-betweens of several methods against the truth: ``rows`` (m, n, H, W, C) frames."""
    n = len(t)
    alpha = np.asarray(truth)[..., 3] > 0 if np.asarray(truth).shape[-1] == 4 else None
    x0, x1, y1, y0 = _box(alpha, margin=6) if alpha is not None else (0, None, None, 0)
    fig, axes = _grid(len(rows) + 1, n, 1.3, 1.75)
    for j in range(n):
        for i, (seq, lab) in enumerate([(truth, "truth")] + list(zip(rows, labels))):
            ax = axes[i, j]
            ax.imshow(over_white(seq[j])[y0:y1, x0:x1])
            ax.set_xticks([])
            ax.set_yticks([])
            if j == 0:
                ax.set_ylabel(lab, fontsize=8)
            if i == 0:
                ax.set_title(f"t = {t[j]:.2f}", fontsize=8)
    return fig


#: Colours of the layer ranks in :func:`three_layer_figure`: visible, first and second hidden.
RANK_COLORS = ("0.8", "tab:purple", "tab:orange")


def three_layers(size=160, n=5):
    """The three-layer pair ``arms_around`` (:func:`~physlab.inbetween.characters.
    occlusion_benchmark_three_layers`) in-betweened three ways: with its masks one per layer
    (three layers where the forearms cross), with the occluded pixels as one region per overlap
    (:func:`~physlab.inbetween.characters.character_occlusions`: two layers) and as one sheet.

    Returns ``(pair, truth (n, H, W, 4), {label: InbetweenResult})``."""
    import warnings

    from physlab.inbetween.pipeline import inbetween

    (pair,) = characters.occlusion_benchmark_three_layers(size)
    k0, k1 = pair.keyframes()
    o0, o1 = pair.occlusions()
    anim = pair.animation(n)
    truth = pair.ground_truth(np.linspace(0, 1, n))
    two = characters.character_occlusions(pair.skeleton1, size)
    runs = {"three layers": dict(occlusions0=o0, occlusions1=o1),
            "two layers": dict(occlusions0=o0, occlusions1=two),
            "one sheet": {}}
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")           # the one sheet warns about the overlap
        for label, kw in runs.items():
            out[label] = inbetween(k0, k1, pair.skeleton0, pair.skeleton1, n, anim, **kw)
    return pair, truth, out


def three_layer_figure(pair, truth, results):
    """Key 1's layered template coloured by layer rank (where it lies under other layers:
    0 visible, 1 first hidden, 2 second hidden; Sec. 5.1) next to the in-between at t = 0.5
    of each run of :func:`three_layers` and the truth, cropped to the arms."""
    tpl = results["three layers"].templates[1]
    mid = len(truth) // 2
    alpha = np.asarray(truth)[..., 3] > 0
    x0, x1, y1, y0 = _box(alpha[mid:mid + 1], margin=2)
    y0, y1 = y0 + int(0.2 * (y1 - y0)), y0 + int(0.6 * (y1 - y0))      # shoulders to hips
    fig, axes = _grid(1, 2 + len(results), 2.2, 1.9)
    axes = axes[0]
    ax = axes[0]
    ax.imshow(over_white(tpl.image))
    for rank in range(1, tpl.n_layers):
        sel = tpl.tris[tpl.layer_rank == rank]
        ax.tripcolor(tpl.X[:, 0], tpl.X[:, 1], sel, facecolors=np.ones(len(sel)),
                     cmap=matplotlib.colors.ListedColormap([RANK_COLORS[min(rank, 2)]]),
                     alpha=0.75, edgecolors="k", linewidth=0.2)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y1, y0)
    ax.set_title("key 1's hidden layers:\n1st purple, 2nd orange", fontsize=8)
    frames = [("truth", truth[mid])] + [(k, r.frames[mid]) for k, r in results.items()]
    for ax, (label, img) in zip(axes[1:], frames):
        ax.imshow(over_white(img)[y0:y1, x0:x1])
        ax.set_title(f"{label}\nt = 0.5", fontsize=8)
    for a in axes:
        a.set_xticks([])
        a.set_yticks([])
    return fig
