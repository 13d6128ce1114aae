"""Demos for lesson 06: skeleton-driven deformation of a drawing (Brodt & Bessmeltsev 2024,
"Skeleton-Driven Inbetweening of Bitmap Character Drawings", Secs. 4.2–4.3, Eq. 1).

Every ``*_demo`` function is a widget callback (keyword parameters in, a
:class:`matplotlib.figure.Figure` out); the other ``*_figure`` / ``*_comparison`` functions
draw the lesson's static figures. The algorithms live in :mod:`physlab.inbetween`
(template, symmetric Dirichlet deformer, LBS / ARAP); this module only wires them to plots.

Coordinates are pixels, y down, as everywhere in :mod:`physlab.inbetween`.
"""
from __future__ import annotations

import numpy as np

from physlab.inbetween import characters
from physlab.inbetween.deform import (MU, TOL, SymmetricDirichletDeformer,
                                      symmetric_dirichlet_density)
from physlab.inbetween.plots import draw_mesh, draw_skeleton, over_white
from physlab.viz.plots import new_figure

__all__ = [
    "SOLVERS", "LIMB_METHODS", "character_template", "triangle_densities", "template_figure",
    "density_figure", "injective_step_figure", "solver_comparison", "pose_arm", "deform_pose",
    "arm_pose_demo", "handle_matrix", "limb_symmetric_dirichlet", "limb_results",
    "elbow_area_loss", "limb_comparison", "limb_demo",
]

#: Solvers compared in the lesson: label → (preconditioner, method) of
#: :meth:`SymmetricDirichletDeformer.solve`.
SOLVERS = {
    "gradient descent": ("none", "gradient"),
    "Sobolev gradient (P⁻¹∇E)": ("sobolev", "gradient"),
    "L-BFGS, Sobolev metric (paper)": ("sobolev", "lbfgs"),
}
_SOLVER_COLORS = ("tab:red", "tab:orange", "tab:blue")

#: Deformers of the bending-limb comparison (labels for plots).
LIMB_METHODS = {"lbs": "linear blend skinning", "arap": "ARAP",
                "symmetric_dirichlet": "symmetric Dirichlet (Eq. 1)"}
_LIMB_SHORT = {"lbs": "LBS", "arap": "ARAP", "symmetric_dirichlet": "Eq. 1"}

#: Paper Fig. 6 colours per-triangle symmetric Dirichlet energy "from grey (low) to red (high)".
_GREY_RED = ("0.88", "#f4a582", "#d6604d", "#b2182b", "#67001f")


def _grey_red():
    from matplotlib.colors import LinearSegmentedColormap

    return LinearSegmentedColormap.from_list("grey_red", _GREY_RED)


def _area_cmap():
    """Diverging area-ratio colours (blue shrunk, white kept, red grown); folded = black."""
    import matplotlib

    return matplotlib.colormaps["RdBu_r"].with_extremes(under="black", over="#67001f")


# ---------------------------------------------------------------------------- checks
def _check_angle(value, name, limit=180.0):
    v = float(value)
    if not np.isfinite(v) or abs(v) > limit:
        raise ValueError(f"{name} must be a finite angle in [-{limit:g}, {limit:g}] degrees, "
                         f"got {value}")
    return v


def _check_mu(mu):
    mu = float(mu)
    if not (np.isfinite(mu) and mu > 0):
        raise ValueError(f"mu must be a finite number > 0 (the paper uses {MU:g}), got {mu}")
    return mu


# ---------------------------------------------------------------------------- template
def character_template(size=256, style="flat", seed=0, max_area=None):
    """The procedural character (:func:`physlab.inbetween.render_character`) at its rest pose
    and its deformation template (:func:`physlab.inbetween.build_template`, Sec. 4.2).

    Parameters
    ----------
    size : int ≥ 64, image size in px (the lesson uses 256: ~160 vertices, fast solves).
    style : one of :data:`physlab.inbetween.CHARACTER_STYLES`.
    seed : int, colours and patterns of the drawing.
    max_area : Triangle's maximum triangle area (px²) or None for the default.

    Returns
    -------
    Template (its ``skeleton`` is the rest skeleton, ``image`` the drawing).
    """
    from physlab.inbetween import build_template

    rest = characters.character_skeleton(size)
    image = characters.render_character(rest, style=style, size=size, seed=seed)
    return build_template(image, rest, max_area=max_area, name=f"character ({style})")


def triangle_densities(template, x):
    """(T,) symmetric Dirichlet density ``‖J_f‖² + ‖J_f⁻¹‖²`` of every triangle of the
    deformed template ``x`` (n, 2) px; 4 for a rigidly moved triangle, +inf if flipped."""
    from physlab.fem import deformation_gradients

    return symmetric_dirichlet_density(deformation_gradients(x, template.X, template.tris))


def _crop(ax, pts, shape, margin=10.0):
    lo = np.maximum(pts.min(0) - margin, -0.5)
    hi = np.minimum(pts.max(0) + margin, np.array(shape[::-1]) - 0.5)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(hi[1], lo[1])


def template_figure(template, epsilon=2.0, grow=3):
    """Sec. 4.2 in three panels: the drawing and its skeleton; the foreground mask with its
    Douglas–Peucker outline (ε = ``epsilon`` px, after growing the mask by ``grow`` px, as
    :func:`~physlab.inbetween.build_template` does); the Triangle mesh with the handles
    (joints ● and bone midpoints ◆) as vertices, over the drawing."""
    from scipy import ndimage

    from physlab.mesh import boundary_polygon

    sk, img = template.skeleton, template.image
    grown = ndimage.binary_dilation(template.mask, iterations=grow) if grow else template.mask
    poly = boundary_polygon(grown, epsilon=epsilon)
    raw = boundary_polygon(grown, epsilon=0.0)
    fig, axes = new_figure(3, width=2.9, height=3.1)
    axes[0].imshow(over_white(img))
    draw_skeleton(axes[0], sk, lw=1.2, ms=3)
    axes[0].set_title(f"drawing + skeleton\n({len(sk)} joints, {len(sk.bones)} bones)", fontsize=8)
    axes[1].imshow(grown, cmap="Greys", vmin=0, vmax=2.5)
    closed = np.vstack([poly, poly[:1]])
    axes[1].plot(*closed.T, "-", color="tab:blue", lw=0.9)
    axes[1].plot(*poly.T, ".", color="tab:blue", ms=2.5)
    axes[1].set_title(f"mask → Douglas–Peucker outline\n({len(raw)} contour points → "
                      f"{len(poly)} at ε = {epsilon:g} px)", fontsize=8)
    axes[2].imshow(over_white(img), alpha=0.55)
    draw_mesh(axes[2], template.X, template.tris, lw=0.35, color="0.25")
    H = sk.handles()
    J = len(sk)
    axes[2].plot(*H[:J].T, "o", color="tab:red", ms=3.5, mec="white", mew=0.4, label="joints")
    axes[2].plot(*H[J:].T, "D", color="tab:orange", ms=2.8, mec="white", mew=0.4,
                 label="bone midpoints")
    axes[2].legend(fontsize=6, loc="upper left", handletextpad=0.2, borderpad=0.3)
    axes[2].set_title(f"Triangle mesh, min angle 20°\n({template.mesh.n} vertices, "
                      f"{template.mesh.n_tris} triangles)", fontsize=8)
    for ax in axes:
        _crop(ax, template.X, template.shape, margin=6.0)
        ax.set_xticks([])
        ax.set_yticks([])
    return fig


# ---------------------------------------------------------------------------- Eq. 1 density
def density_figure(s_min=-0.6, s_max=3.0):
    """Energy densities of the 1-parameter family ``J = diag(1, s)`` (squash s < 1, stretch
    s > 1, collapse at s = 0, fold for s < 0), and level sets of ``ψ(σ₁, σ₂)``.

    Left: ``‖J‖² + ‖J⁻¹‖²`` (symmetric Dirichlet, = 4 at s = 1, → ∞ at collapse and
    undefined (+∞) once folded), its first term ``‖J‖²`` alone (plain Dirichlet: *cheapest* at
    collapse), and the corotated ``‖J − R‖²`` of lesson 04 (finite through collapse and fold).
    Right: ``ψ = σ₁² + σ₂² + σ₁⁻² + σ₂⁻²`` over the singular values.
    """
    from matplotlib.colors import LogNorm

    from physlab.fem import polar_rotation

    s = np.linspace(s_min, s_max, 721)
    J = np.zeros((len(s), 2, 2))
    J[:, 0, 0], J[:, 1, 1] = 1.0, s
    sd = symmetric_dirichlet_density(J)
    dirichlet = np.sum(J * J, axis=(1, 2))
    corot = np.sum((J - polar_rotation(J)) ** 2, axis=(1, 2))
    fig, (ax, ax2) = new_figure(2, width=4.0, height=3.1)
    ax.axvspan(s_min, 0.0, color="0.92", lw=0)
    ax.text(0.5 * s_min, 10.7, "folded\n(det J < 0)", ha="center", va="top", fontsize=7)
    ax.plot(s, np.where(np.isfinite(sd), sd, np.nan), color="tab:red", lw=2,
            label="‖J‖² + ‖J⁻¹‖²  (symmetric Dirichlet)")
    ax.plot(s, dirichlet, "--", color="tab:purple", label="‖J‖²  (Dirichlet alone)")
    ax.plot(s, corot, color="tab:green", label="‖J − R‖²  (corotated / ARAP)")
    ax.plot([1.0], [4.0], "ko", ms=4)
    ax.annotate("rotation: ψ = 4", (1.0, 4.0), xytext=(1.35, 6.2), fontsize=7,
                arrowprops={"arrowstyle": "-", "lw": 0.6})
    ax.axvline(0.0, color="0.4", lw=0.6, ls=":")
    ax.set_ylim(0, 11)
    ax.set_xlim(s_min, s_max)
    ax.set_xlabel("s in J = diag(1, s)   (area ratio det J)")
    ax.set_ylabel("energy density")
    ax.legend(fontsize=6.5, loc="upper right")
    g = np.linspace(0.12, 3.0, 300)
    s1, s2 = np.meshgrid(g, g)
    psi = s1**2 + s2**2 + s1**-2 + s2**-2
    levels = [4.05, 4.5, 5, 6, 8, 12, 20, 40, 80]
    cs = ax2.contourf(s1, s2, psi, levels=[4] + levels[1:] + [psi.max()], cmap=_grey_red(),
                      norm=LogNorm(4, 80))
    ax2.contour(s1, s2, psi, levels=levels, colors="0.3", linewidths=0.4)
    ax2.plot([1], [1], "ko", ms=4)
    ax2.set_xlabel("σ₁")
    ax2.set_ylabel("σ₂")
    ax2.set_aspect("equal")
    ax2.set_title("ψ(σ₁, σ₂): min 4 at σ₁ = σ₂ = 1, ∞ on the axes", fontsize=8)
    fig.colorbar(cs, ax=ax2, shrink=0.85, label="ψ", ticks=[4, 6, 12, 20, 40, 80],
                 format="%g")
    return fig


# ---------------------------------------------------------------------------- Smith–Schaefer
def injective_step_figure(x, d, alphas=(0.0, 0.25, 0.5, 0.75, 1.2)):
    """One triangle ``x`` (3, 2) moved along ``d`` (3, 2): the triangle at the steps
    ``alphas`` (left: degenerate black, folded dashed red, unfolded again beyond the first
    root dotted purple) and ``det Ds(α) = aα² + bα + c`` (right, the same steps as dots) with
    its first positive root, the Smith–Schaefer bound :func:`max_injective_step`."""
    from physlab.inbetween.deform import max_injective_step

    x, d = np.asarray(x, float), np.asarray(d, float)
    tri = np.array([[0, 1, 2]])
    amax = max_injective_step(x, d, tri)
    fig, (ax, ax2) = new_figure(2, width=3.6, height=3.0)
    shades = ("0.75", "tab:blue", "tab:cyan")
    marks = []
    for k, a in enumerate(alphas):
        y = x + a * d
        det = np.linalg.det(np.stack([y[1] - y[0], y[2] - y[0]], -1))
        if abs(det) < 1e-9:
            style, note = {"ec": "k", "lw": 2.0}, "degenerate"
        elif det < 0:
            style, note = {"ec": "tab:red", "lw": 1.4, "ls": "--"}, "folded"
        elif a > amax:
            style, note = {"ec": "tab:purple", "lw": 1.4, "ls": ":"}, "det > 0 again!"
        else:
            style, note = {"ec": shades[k % len(shades)], "lw": 1.4}, "ok"
        ax.fill(*y.T, fc="none", label=f"α = {a:g} ({note})", **style)
        marks.append((a, det, style["ec"]))
    ax.plot(*x.T, "ko", ms=3)
    ax.set_aspect("equal")
    ax.legend(fontsize=6.5, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2)
    ax.set_title("one triangle at x + α d", fontsize=8)
    a = np.linspace(0.0, max(alphas) * 1.1, 300)
    Ds = np.stack([x[1] - x[0], x[2] - x[0]], -1)
    dD = np.stack([d[1] - d[0], d[2] - d[0]], -1)
    det = np.array([np.linalg.det(Ds + t * dD) for t in a])
    ax2.plot(a, det, color="0.2", lw=1.8, label="det(Ds + α dDs)")
    for a_k, det_k, c in marks:  # the triangles drawn on the left
        ax2.plot(a_k, det_k, "o", color=c, ms=6, mec="k", mew=0.5, zorder=3)
    ax2.axhline(0, color="0.3", lw=0.6)
    if np.isfinite(amax):
        ax2.axvspan(amax, a[-1], color="tab:red", alpha=0.08)
        ax2.axvline(amax, color="tab:red", lw=1, ls="--")
        ax2.annotate(f"α_max = {amax:.3g}\n(first root)", (amax, 0), xytext=(amax + 0.05,
                     0.6 * det.max()), fontsize=7, color="tab:red")
    ax2.set_xlabel("step α")
    ax2.set_ylabel("det Ds(α)  (∝ signed area)")
    ax2.legend(fontsize=7, loc="lower left")
    return fig


# ---------------------------------------------------------------------------- solvers
def solver_comparison(template, targets, max_iter=800, tol=TOL, mu=MU):
    """Solve Eq. (1) for one pose with each of :data:`SOLVERS` from the rest mesh and plot
    energy gap ``E_k − E*`` and Sobolev gradient norm ``‖∇E‖_P⁻¹`` per iteration (log y).

    ``targets`` : a posed Skeleton or (K, 2) handle targets (px). ``E*`` is the lowest
    energy any run reached. Returns ``(fig, results)`` with ``results`` a dict label →
    :class:`~physlab.inbetween.deform.DeformResult` (histories recorded).
    """
    results = {}
    for label, (pre, method) in SOLVERS.items():
        D = SymmetricDirichletDeformer(template, mu=mu, preconditioner=pre)
        results[label] = D.solve(targets, tol=tol, max_iter=max_iter, method=method,
                                 record=True)
    e_star = min(min(r.history["energy"]) for r in results.values())
    fig, (ax, ax2) = new_figure(2, width=4.0, height=3.0)
    for (label, r), c in zip(results.items(), _SOLVER_COLORS):
        e = np.asarray(r.history["energy"]) - e_star
        it = np.arange(len(e))
        tag = f"{label}: {r.iterations} it." + ("" if r.converged else " (not converged)")
        ax.semilogy(it, np.maximum(e, 1e-12), color=c, lw=1.4, label=tag)
        ax2.semilogy(it, r.history["grad_norm"], color=c, lw=1.4)
    ax2.axhline(tol, color="k", lw=0.8, ls=":")
    ax2.text(max_iter * 0.98, tol * 1.4, f"tol = {tol:g}", ha="right", fontsize=7)
    ax.set_ylim(1e-10, None)
    ax.set_xlabel("iteration")
    ax2.set_xlabel("iteration")
    ax.set_ylabel("E − E*")
    ax2.set_ylabel("Sobolev gradient norm ‖∇E‖_P⁻¹")
    ax.legend(fontsize=6.5, loc="lower left")
    for a_ in (ax, ax2):
        a_.grid(True, which="major", alpha=0.3)
        a_.set_xscale("symlog", linthresh=10)
        a_.set_xlim(0, max_iter)
    return fig, results


# ---------------------------------------------------------------------------- arm widget
def pose_arm(rest, shoulder_deg=-60.0, elbow_deg=-60.0):
    """The character ``rest`` skeleton with its left arm (image right) turned: the upper arm
    by ``shoulder_deg`` about the shoulder, the forearm by ``elbow_deg`` about the elbow
    (degrees, positive = clockwise on screen; negative raises the arm)."""
    shoulder_deg = _check_angle(shoulder_deg, "shoulder_deg")
    elbow_deg = _check_angle(elbow_deg, "elbow_deg")
    return characters.pose_character(rest, left_upper_arm=shoulder_deg, left_forearm=elbow_deg)


def deform_pose(template, pose, mu=MU):
    """Deform ``template`` into the Skeleton ``pose`` by Eq. (1), through intermediate poses
    when handles move far (:func:`physlab.inbetween.pipeline.deform_sequence`).

    Returns ``(x, info)``: (n, 2) vertices (px) and a dict with ``energy_d`` (E_d),
    ``handle_error`` (max, px), ``flipped`` (count), ``density`` ((T,) per-triangle ψ).
    """
    from physlab.inbetween.pipeline import deform_sequence

    xs, e_d, err, flipped = deform_sequence(template, [pose], mu=_check_mu(mu))
    x = xs[0]
    return x, {"energy_d": float(e_d[0]), "handle_error": float(err[0]),
               "flipped": int(flipped[0]), "density": triangle_densities(template, x)}


def arm_pose_demo(shoulder_deg=-60.0, elbow_deg=-60.0, mu=MU, size=256, style="flat"):
    """Widget callback: drag the character's left arm (shoulder and elbow angles relative to
    the rest pose) and deform the drawing by Eq. (1) with pose weight ``mu``.

    Left: the warped drawing with the target skeleton; right: the deformed mesh coloured by
    the per-triangle symmetric Dirichlet density ψ (grey = 4 = rigid, red = distorted, as in
    the paper's Fig. 6). The title reports the flipped-triangle count (always 0: the energy
    is infinite for a flipped triangle and the line search never crosses one), the largest
    handle error and E_d.
    """
    from matplotlib.colors import LogNorm

    mu = _check_mu(mu)
    tpl = character_template(size=size, style=style)
    pose = pose_arm(tpl.skeleton, shoulder_deg, elbow_deg)
    x, info = deform_pose(tpl, pose, mu=mu)
    img = tpl.render(x)
    fig, (ax, ax2) = new_figure(2, width=3.5, height=3.7)
    ax.imshow(over_white(img))
    draw_skeleton(ax, pose, lw=1.0, ms=2.5, handles=True)
    ax.set_title("warped drawing + target skeleton", fontsize=8)
    art = draw_mesh(ax2, x, tpl.tris, values=np.minimum(info["density"], 1e6), cmap=_grey_red(),
                    lw=0.3, color="0.35")
    art.set_norm(LogNorm(4.0, 12.0))
    ax2.plot(*pose.handles().T, ".", color="k", ms=2.5)
    ax2.set_title("per-triangle ψ = ‖J‖² + ‖J⁻¹‖²", fontsize=8)
    fig.colorbar(art, ax=ax2, shrink=0.75, ticks=[4, 5, 6, 8, 10, 12], format="%g",
                 label="ψ (4 = rigid)")
    pts = np.vstack([x, tpl.X])
    for a in (ax, ax2):
        _crop(a, pts, tpl.shape, margin=8.0)
        a.set_xticks([])
        a.set_yticks([])
    fig.suptitle(f"shoulder {shoulder_deg:+.0f}°, elbow {elbow_deg:+.0f}°, μ = {mu:g}:  "
                 f"flipped triangles {info['flipped']},  max handle error "
                 f"{info['handle_error']:.2g} px,  E_d = {info['energy_d']:.3f}", fontsize=8)
    return fig


# ---------------------------------------------------------------------------- bending limb
def handle_matrix(handle_vertices, n):
    """Sparse (K, n) one-hot matrix ``B`` with ``B @ x = x[handle_vertices]`` — the handle
    matrix of Eq. (1)'s ``E_pose`` for handles that are mesh vertices (all entries ≥ 0)."""
    from scipy import sparse

    hv = np.asarray(handle_vertices)
    if hv.ndim != 1 or len(hv) == 0 or not np.issubdtype(hv.dtype, np.integer):
        raise ValueError(f"handle_vertices must be a non-empty 1D int array, got {hv!r}")
    if hv.min() < 0 or hv.max() >= n:
        raise ValueError(f"handle_vertices must index vertices 0..{n - 1} (a handle that is not "
                         f"a vertex needs barycentric rows: Template.handle_matrix()); got "
                         f"{hv.tolist()}")
    K = len(hv)
    return sparse.csr_matrix((np.ones(K), (np.arange(K), hv)), shape=(K, n))


def limb_symmetric_dirichlet(example, mu=MU, max_handle_step=16.0):
    """Deform a :class:`~physlab.inbetween.skinning.LimbExample` into its posed skeleton by
    Eq. (1), through intermediate bends (handles move ≤ ``max_handle_step`` px per solve,
    each solve warm-started from the previous one). Returns the (n, 2) vertices."""
    from physlab.inbetween.pipeline import substeps

    D = SymmetricDirichletDeformer(example.X, example.tris,
                                   handle_matrix(example.handle_vertices, len(example.X)),
                                   mu=_check_mu(mu))
    x = None
    for s in substeps(example.skeleton_rest, example.skeleton_pose, max_handle_step):
        x = D.solve(s.handles(), x0=x).x
    return x


def elbow_area_loss(example, x):
    """Fraction of the elbow region's rest area lost in ``x``: ``1 − Σ a_f / Σ A_f`` over
    ``example.elbow_tris`` (signed areas; folded triangles count negative)."""
    from physlab.mesh import triangle_areas

    t = example.tris[example.elbow_tris]
    return float(1.0 - triangle_areas(x, t).sum() / triangle_areas(example.X, t).sum())


def limb_results(angle_deg=120.0):
    """The bending arm (:func:`~physlab.inbetween.skinning.bending_limb_example`) deformed
    by LBS, ARAP and Eq. (1). Returns ``(example, xs, stats)``: ``xs`` method → (n, 2);
    ``stats`` method → dict ``area_loss`` (elbow), ``flipped`` (count), ``min_ratio``
    (smallest triangle area ratio)."""
    from physlab.inbetween.skinning import (bending_limb_example, flipped_triangles,
                                            triangle_area_ratios)

    angle_deg = _check_angle(angle_deg, "angle_deg", limit=175.0)
    ex = bending_limb_example(angle_deg)
    xs = {"lbs": ex.results["lbs"], "arap": ex.results["arap"],
          "symmetric_dirichlet": limb_symmetric_dirichlet(ex)}
    stats = {m: {"area_loss": elbow_area_loss(ex, x),
                 "flipped": len(flipped_triangles(ex.X, x, ex.tris)),
                 "min_ratio": float(triangle_area_ratios(ex.X, x, ex.tris).min())}
             for m, x in xs.items()}
    return ex, xs, stats


def _draw_limb(ax, ex, x, stats, method, zoom=0.0, box=None):
    from physlab.inbetween.skinning import triangle_area_ratios

    ratio = triangle_area_ratios(ex.X, x, ex.tris)
    art = draw_mesh(ax, x, ex.tris, values=ratio, cmap=_area_cmap(), vmin=1e-9, vmax=2.0,
                    lw=0.25, color="0.4")
    bad = ratio <= 1e-6
    for t in ex.tris[bad]:  # folded / collapsed: black, circled
        ax.fill(*x[t].T, fc="black", ec="yellow", lw=0.8, zorder=3)
        ax.plot(*x[t].mean(0), "o", mfc="none", mec="k", ms=13, mew=1.2, zorder=4)
    draw_skeleton(ax, ex.skeleton_pose, color="k", lw=0.8, ms=2.5)
    st = stats[method]
    ax.set_title(f"{LIMB_METHODS[method]}\nelbow area loss {100 * st['area_loss']:.1f} %, "
                 f"flipped {st['flipped']}", fontsize=8)
    if box is not None:                       # (x0, y0, x1, y1): the whole limb, shoulder to hand
        ax.set_xlim(box[0], box[2])
        ax.set_ylim(box[3], box[1])
        ax.set_aspect("equal")
    elif zoom:
        e = ex.skeleton_pose.xy[1]
        w = zoom * (ex.X[:, 1].max() - ex.X[:, 1].min())
        ax.set_xlim(e[0] - w, e[0] + w)
        ax.set_ylim(e[1] + w, e[1] - w)
    ax.set_xticks([])
    ax.set_yticks([])
    return art


def limb_comparison(angle_deg=120.0):
    """Three panels (LBS, ARAP, Eq. 1) of the arm bent by ``angle_deg``, the whole limb from
    shoulder to hand on one scale, coloured by triangle area ratio (blue shrunk, red grown, black folded or
    collapsed, outlined yellow). Returns ``(fig, stats)`` (see :func:`limb_results`)."""
    ex, xs, stats = limb_results(angle_deg)
    pts = np.concatenate(list(xs.values()) + [ex.skeleton_pose.xy])
    pad = 0.04 * np.ptp(pts, axis=0).max()
    box = (*(pts.min(0) - pad), *(pts.max(0) + pad))
    aspect = (box[3] - box[1]) / (box[2] - box[0])
    fig, axes = new_figure(3, width=2.7, height=min(2.7 * aspect + 0.6, 4.0))
    for ax, m in zip(axes, xs):
        art = _draw_limb(ax, ex, xs[m], stats, m, box=box)
    fig.colorbar(art, ax=list(axes), shrink=0.8, extend="both",
                 label="area ratio a_f / A_f (black ≤ 0)")
    fig.suptitle(f"forearm bent {angle_deg:g}° at the elbow", fontsize=9)
    return fig, stats


def limb_demo(angle_deg=120.0, method="symmetric_dirichlet"):
    """Widget callback: the arm bent by ``angle_deg`` with one deformer (``method`` in
    :data:`LIMB_METHODS`): the whole arm and a zoom on the elbow, coloured by area ratio."""
    if method not in LIMB_METHODS:
        raise ValueError(f"method must be one of {list(LIMB_METHODS)}, got {method!r}")
    ex, xs, stats = limb_results(angle_deg)
    fig, (ax, ax2) = new_figure(2, width=3.4, height=3.0)
    _draw_limb(ax, ex, xs[method], stats, method)
    art = _draw_limb(ax2, ex, xs[method], stats, method, zoom=0.9)
    ax2.set_title("elbow (zoom)", fontsize=8)
    fig.colorbar(art, ax=ax2, shrink=0.8, extend="both", label="area ratio (black ≤ 0)")
    fig.suptitle(f"bend {angle_deg:g}°, flipped triangles: " + ",  ".join(
        f"{_LIMB_SHORT[m]}: {s['flipped']}" for m, s in stats.items()), fontsize=8)
    return fig
