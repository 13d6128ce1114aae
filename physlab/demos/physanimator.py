"""Demos for PhysAnimator (lessons 04–05): Fixed Corotated FEM, energy strokes, rigs, contacts,
built on the drawing → simulation → rendered animation pipeline of
:mod:`physlab.physanimator.pipeline`.

Every ``*_demo`` function is a widget callback (keyword parameters in, a
:class:`matplotlib.figure.Figure` out). Scene builders return :class:`physlab.physanimator.Scene`
objects; :func:`animate` runs a scene and renders it.

Rendering is physlab's honest CPU substitute for the paper's sketch-guided video diffusion
(ToonCrafter + ControlNet, weights not available offline): the drawing is warped by the
simulated mesh (:class:`physlab.render.WarpRenderer`), and the per-frame control images such
a model would consume are produced alongside (:func:`physlab.render.edge_map`).
"""
from __future__ import annotations

import functools

import numpy as np

from physlab import datasets, fem
from physlab import physanimator as pa
from physlab.mesh import grid_mesh
from physlab.physanimator.pipeline import (AnimationResult, _strip, animate,  # noqa: F401
                                           animate_drawing, drawing_body)
from physlab.viz import plots

__all__ = [
    "drawing_body", "animate", "AnimationResult", "max_strain", "element_demo", "flow_field_demo",
    "ball_push_scene", "youngs_modulus_sweep", "max_strain_frame", "tree_scene", "flag_scene", "collision_scene",
    "stroke_demo", "flag_demo", "filmstrip", "ball_push_demo", "animate_drawing",
]


# The pipeline (drawing_body, animate, AnimationResult, animate_drawing) lives in
# physlab.physanimator.pipeline; its names stay importable from here for the lessons.

def max_strain(anim, body=0):
    """Largest principal strain ``max |σ_i(F) - 1|`` over triangles and frames of one body."""
    return max(max_strain_frame(anim, k, body) for k in range(anim.n_frames))


def _crop_to_content(frames, controls=None, pad=6):
    """Frames (and controls) cut to the box, over all of them, of the pixels that differ
    from the background colour of the top-left pixel (plus ``pad``): no empty canvas."""
    F = np.stack(frames)
    bg = F[0, 0, 0]
    ink = np.any(F != bg, axis=-1).any(axis=0)                             # (H, W)
    if not ink.any():
        return F, None if controls is None else np.stack(controls)
    rows, cols = np.flatnonzero(ink.any(1)), np.flatnonzero(ink.any(0))
    r0, r1 = max(rows[0] - pad, 0), min(rows[-1] + pad + 1, F.shape[1])
    c0, c1 = max(cols[0] - pad, 0), min(cols[-1] + pad + 1, F.shape[2])
    C = None if controls is None else np.stack(controls)[:, r0:r1, c0:c1]
    return F[:, r0:r1, c0:c1], C


def filmstrip(frames, n=6, controls=None, width=1.6, index=None):
    """A figure with ``n`` evenly spaced frames (and their control images below); ``index``:
    the frame numbers of ``frames`` when they are a selection (titles)."""
    idx = _strip(len(frames), n)
    frames, controls = _crop_to_content([frames[k] for k in idx],
                                        None if controls is None else [controls[k] for k in idx])
    idx_shown, idx = idx, np.arange(len(idx))
    rows = 2 if controls is not None else 1
    fig, axes = plots.new_figure(len(idx), rows, width=width, height=width * frames.shape[1] / frames.shape[2])
    axes = np.asarray(axes).reshape(rows, len(idx))
    for j, k in enumerate(idx):
        shown = idx_shown[k]
        axes[0, j].imshow(frames[k])
        axes[0, j].set_title(f"frame {shown if index is None else int(index[shown])}",
                             fontsize=8)
        if controls is not None:
            axes[1, j].imshow(controls[k], cmap="gray", vmin=0, vmax=255)
    for ax in axes.ravel():
        ax.set_axis_off()
    return fig


# ---------------------------------------------------------------------------- lesson 04

def element_demo(stretch_x=1.3, stretch_y=1.0, shear=0.0, rotation_deg=0.0, E=1e3, nu=0.3):
    """A 4 × 4 patch under the affine map ``x = R(θ) [[sx, k], [0, sy]] X``: energy density Ψ
    per triangle (colour), elastic forces (arrows) and the total energy."""
    mesh = grid_mesh(4, 4, 1.0, 1.0)
    X, tris = mesh.X, mesh.tris
    th = np.deg2rad(rotation_deg)
    A = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]]) @ np.array(
        [[stretch_x, shear], [0.0, stretch_y]])
    x = (X - 0.5) @ A.T + 0.5
    mu, lam = fem.lame_parameters(E, nu)
    F = fem.deformation_gradients(x, X, tris)
    psi = fem.fixed_corotated_energy_density(F, mu, lam)
    f = fem.elastic_forces(x, X, tris, mu, lam)
    fig, ax = plots.new_figure(width=4.2, height=4.0)
    ax.triplot(X[:, 0], X[:, 1], tris, color="0.8", lw=0.6)
    # fixed colour scale (energy density of a 50 % stretch), so colours compare across settings
    tp = ax.tripcolor(x[:, 0], x[:, 1], tris, facecolors=psi, cmap="YlOrRd", edgecolors="0.3",
                      lw=0.4, vmin=0, vmax=max(psi.max(), (mu + lam / 2) * 0.25))
    scale = 0.25 / max(np.abs(f).max(), 1e-12)
    ax.quiver(x[:, 0], x[:, 1], f[:, 0] * scale, f[:, 1] * scale, angles="xy", scale_units="xy",
              scale=1, color="tab:blue", width=0.006)
    tips = np.concatenate([x, x + f * scale, X])
    lo, hi = tips.min(0) - 0.05, tips.max(0) + 0.05
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    fig.colorbar(tp, ax=ax, shrink=0.7, label="Ψ(F)")
    ax.set_aspect("equal")
    ax.set_title(f"total energy Σ Ψ V = {fem.elastic_energy(x, X, tris, mu, lam):.4g}, "
                 f"|Σ f| = {np.abs(f.sum(0)).max():.1e}", fontsize=8)
    return fig


def flow_field_demo(strength=1.0, range=1.0, direction_deg=0.0):
    """The three flow particles' force fields around a particle at the origin (Fig. 1)."""
    g = np.linspace(-1.3 * range, 1.3 * range, 15)
    q = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    d = (np.cos(np.deg2rad(direction_deg)), np.sin(np.deg2rad(direction_deg)))
    from matplotlib.colors import Normalize
    from matplotlib.patches import Circle

    fig, axes = plots.new_figure(3, 1, width=2.8, height=3.1)
    forces = {kind: pa.flow_force(kind, (0.0, 0.0), q, strength, range, d)
              for kind in pa.FLOW_KINDS}
    norm = Normalize(0.0, max(float(np.linalg.norm(f, axis=1).max()) for f in forces.values()))
    for ax, (kind, f) in zip(axes, forces.items()):
        qv = ax.quiver(q[:, 0], q[:, 1], f[:, 0], f[:, 1], np.linalg.norm(f, axis=1),
                       cmap="viridis", norm=norm, angles="xy", width=0.008)
        ax.add_patch(Circle((0, 0), range, fill=False, ls=":"))
        ax.plot(0, 0, "r*", ms=10)
        ax.set_title(kind + (" (Eq. 8)" if kind == "wind" else " (Eq. 9)"), fontsize=9)
        ax.set_aspect("equal")
        ax.invert_yaxis()  # image coordinates, y down
        ax.set_xlabel("x (range units)", fontsize=7)
    # the wind's direction d, drawn outside the field in the first panel
    a0 = axes[0]
    a0.annotate("", xy=(-1.25 * range + 0.5 * range * d[0], -1.2 * range + 0.5 * range * d[1]),
                xytext=(-1.25 * range, -1.2 * range),
                arrowprops=dict(arrowstyle="-|>", color="tab:red", lw=1.5))
    a0.text(-1.25 * range, -1.45 * range, "d", color="tab:red", fontsize=8)
    fig.colorbar(qv, ax=axes, orientation="horizontal", shrink=0.5, pad=0.2,
                 label="|f| per vertex (force units of s)")
    fig.suptitle("flow particle (red star) at the origin, range r dotted; arrows: force on a "
                 "vertex there", fontsize=8)
    return fig


def ball_push_scene(E=2e5, nu=0.3, strength=2e4, size=160, seed=0):
    """Fig. 5 setting: a wind stroke blows a cartoon ball against a wall on its right; a soft
    ball flattens against it, a stiff one keeps its shape."""
    ball = datasets.cartoon_ball(size=size, seed=seed)
    body = drawing_body(ball, E=E, nu=nu, offset=(30.0, 20.0))
    wall = 30.0 + size + 12.0
    y = 20.0 + 0.5 * size
    stroke = pa.EnergyStroke([[0.0, y], [wall, y]], "wind", strength=strength,
                             range=0.6 * size, speed=150.0, n_particles=2, loop=True)
    return pa.Scene([body], strokes=[stroke], walls=(0.0, wall), damping=2.0,
                    size=(int(wall) + 20, size + 40))


def youngs_modulus_sweep(Es=(5e4, 1e5, 2e5, 4e5), duration=1.5, strength=2e4, size=160):
    """The same push on balls of increasing Young's modulus (Fig. 5). Returns
    ``(fig, strains)``: each ball at its most strained frame — triangles coloured by their
    largest principal strain ``max|σ_i(F) − 1|`` on one shared scale, the rest outline dashed,
    the wall grey, all panels cropped to the same window — and the max strains."""
    runs = []
    for E in Es:
        scene = ball_push_scene(E, strength=strength, size=size)
        anim = pa.simulate(scene, duration, progress=False)
        per_frame = [max_strain_frame(anim, k) for k in range(anim.n_frames)]
        k = int(np.argmax(per_frame))
        b = scene.bodies[0]
        Fk = fem.deformation_gradients(anim.x[0][k], b.X_canvas, b.mesh.tris)
        tri_strain = np.abs(np.linalg.svd(Fk, compute_uv=False) - 1).max(axis=1)   # (T,)
        runs.append((scene, anim.x[0][k], tri_strain, float(per_frame[k])))
    vmax = max(r[2].max() for r in runs)
    pts = np.concatenate([np.concatenate([r[1], r[0].bodies[0].X_canvas]) for r in runs])
    wall = runs[0][0].walls[1]
    (x0, y0), (x1, y1) = pts.min(0) - 6, pts.max(0) + 6
    x1 = max(x1, wall + 6)
    fig, axes = plots.new_figure(len(Es), 1, width=1.9, height=1.9 * (y1 - y0) / (x1 - x0) + 0.5)
    for ax, E, (scene, x, strain, smax) in zip(np.atleast_1d(axes), Es, runs):
        b = scene.bodies[0]
        tp = ax.tripcolor(x[:, 0], x[:, 1], b.mesh.tris, facecolors=strain, cmap="magma_r",
                          vmin=0.0, vmax=vmax, edgecolors="none")
        rest = b.X_canvas[b.mesh.boundary_edges()]                              # (E, 2, 2)
        ax.plot(*np.transpose(rest, (2, 1, 0)), color="0.35", lw=0.8, ls="--")
        ax.axvline(wall, color="0.5", lw=3)
        ax.set_xlim(x0, x1)
        ax.set_ylim(y1, y0)                                                     # image: y down
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(f"E = {E:.0e}\nmax strain {smax:.2f}", fontsize=8)
    fig.colorbar(tp, ax=np.atleast_1d(axes), shrink=0.8, label="principal strain |σ − 1|")
    fig.suptitle("dashed: rest shape; grey bar: the wall the wind pushes the ball against",
                 fontsize=7)
    return fig, [r[3] for r in runs]


def max_strain_frame(anim, k, body=0):
    """Largest principal strain ``max |σ_i(F) - 1|`` of one body at frame ``k``."""
    b = anim.scene.bodies[body]
    F = fem.deformation_gradients(anim.x[body][k], b.X_canvas, b.mesh.tris)
    return float(np.abs(np.linalg.svd(F, compute_uv=False) - 1).max())


# ---------------------------------------------------------------------------- lesson 05

def tree_scene(strength=4e4, range=90.0, direction_deg=0.0, speed=300.0, E=1.5e5, size=256,
               seed=0):
    """A cartoon tree pinned at its trunk base; a wind stroke sweeps across its crown (Fig. 6).

    The canvas is twice the drawing's size, the tree in its middle, so that the crown stays
    in the picture under the strongest wind of the lesson's slider (8e4) from any direction
    (figures crop to what moved: :func:`filmstrip`)."""
    tree = datasets.cartoon_tree(size=size, seed=seed)
    off = np.array([size / 2, size / 2])
    body = drawing_body(tree, E=E, offset=tuple(off))
    pins = tree.pins if len(tree.pins) else np.array([[size / 2, size - 5.0]])
    rigs = [pa.FixedRig(body=0, center=tuple(p + off), radius=0.08 * size) for p in pins]
    th = np.deg2rad(direction_deg)
    c, L = np.array([size / 2, 0.38 * size]) + off, 0.7 * size
    d = np.array([np.cos(th), np.sin(th)])
    stroke = pa.EnergyStroke([c - L * d, c + L * d], "wind", strength=strength, range=range,
                             speed=speed, n_particles=3, loop=True)
    return pa.Scene([body], strokes=[stroke], rigs=rigs, damping=2.0, size=(2 * size, 2 * size))


def flag_scene(frequency=6.0, amplitude=12.0, E=8e4, size=256, seed=0):
    """A flag: cloth pinned along its pole; a wavy rig (Eq. 10) on its free edge moves up and
    down, so the cloth waves."""
    flag = datasets.cartoon_flag(size=size, seed=seed)
    body = drawing_body(flag, E=E)
    X = body.mesh.X
    pins = flag.pins if len(flag.pins) else X[np.argsort(X[:, 0])[:3]]
    rigs = [pa.FixedRig(body=0, center=tuple(p), radius=0.06 * size) for p in pins]
    free = X[np.argmax(X[:, 0])]
    rigs.append(pa.WavyRig(body=0, center=tuple(free), radius=0.12 * size, amplitude=amplitude,
                           frequency=frequency, direction=(0.0, 1.0)))
    return pa.Scene([body], rigs=rigs, damping=1.0, size=(size, size))


def collision_scene(E=1e6, size=140, seed=0):
    """Two jelly characters dropped onto each other and the ground (Fig. 7)."""
    a = datasets.jelly_character(size=size, seed=seed)
    b = datasets.cartoon_ball(size=int(size * 0.8), seed=seed + 1)
    W, H = int(2.6 * size), int(3.0 * size)
    lower = drawing_body(a, E=E, offset=(0.55 * size, H - size - 10.0), depth=1.0)
    upper = drawing_body(b, E=E, offset=(0.75 * size, 0.3 * size), depth=0.0)
    return pa.Scene([lower, upper], gravity=(0.0, 980.0), ground=H - 8.0, walls=(0.0, float(W)),
                    restitution=0.3, friction=0.4, damping=0.5, size=(W, H))


def stroke_demo(strength=4e4, range=90.0, direction_deg=0.0, duration=1.5):
    """Widget callback: the tree under one wind stroke; filmstrip of rendered frames."""
    r = animate(tree_scene(strength, range, direction_deg), duration, control=False,
                frames=6)
    return filmstrip(r.frames, n=6, index=r.frame_index)


def flag_demo(frequency=6.0, amplitude=12.0, duration=1.5):
    """Widget callback: the flag driven by a wavy rig (Eq. 10); frames and control images."""
    r = animate(flag_scene(frequency, amplitude), duration, control=True,
                frames=6)
    return filmstrip(r.frames, n=6, controls=r.controls, index=r.frame_index)


def ball_push_demo(E=1e5, nu=0.3, dt=1e-3, duration=1.5):
    """Widget callback: the Fig. 5 push (ball blown against a wall) for one material and time
    step. Too large a ``dt`` shows the stability error and the CFL estimate instead of frames."""
    import warnings

    scene = ball_push_scene(E, nu)
    with warnings.catch_warnings():  # the figure reports the step size problem itself
        warnings.simplefilter("ignore")
        try:
            r = animate(scene, duration, dt=dt, control=False,
                        frames=5)
        except pa.UnstableTimeStep as err:
            fig, ax = plots.new_figure(width=6.0, height=1.2)
            ax.set_axis_off()
            ax.text(0.0, 0.5, f"{type(err).__name__}: {err}", fontsize=8, wrap=True, va="center")
            return fig
    fig = filmstrip(r.frames, n=5, index=r.frame_index)
    for ax in fig.axes:
        ax.axvline(scene.walls[1], color="0.4", lw=3)
    limit, est = _stable_dt(float(E), float(nu))
    fig.suptitle(f"Young's modulus {E:.3g}, ν = {nu:.2f}, dt = {dt:.2g} s: max strain "
                 f"{max_strain(r.animation):.2f}\nCFL estimate dt ≤ {est:.2g} s is conservative: "
                 f"this ball blows up only above dt ≈ {limit:.2g} s ({limit / est:.1f}×)",
                 fontsize=8)
    return fig


@functools.lru_cache(maxsize=32)
def _stable_dt(E, nu):
    """(measured stable dt, CFL estimate) of :func:`ball_push_scene` (E, nu), cached."""
    return pa.measured_stable_dt(ball_push_scene(E, nu), duration=0.5)


