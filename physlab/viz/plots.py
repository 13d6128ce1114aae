"""Static figures used by the lessons (matplotlib, no pyplot global state)."""
from __future__ import annotations

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

__all__ = ["new_figure", "draw_springs", "plot_convergence", "plot_stability_regions",
           "plot_snapshots", "plot_newton_residuals"]

#: One colour per integration method, shared by all lesson plots.
METHOD_COLORS = {
    "exact": "black",
    "explicit_euler": "tab:red",
    "midpoint": "tab:orange",
    "heun": "tab:olive",
    "rk4": "tab:purple",
    "implicit_euler": "tab:blue",
    "trapezoidal": "tab:cyan",
    "semi_implicit_euler": "tab:green",
}


def new_figure(ncols=1, nrows=1, width=4.2, height=3.2, **subplot_kw):
    """A :class:`Figure` with ``ncols`` columns and ``nrows`` rows of axes (note the order:
    columns first, as lessons mostly lay panels side by side); returns ``(fig, axes)``.

    ``width``/``height`` are per panel, in inches (lessons keep figures small)."""
    fig = Figure(figsize=(width * ncols, height * nrows), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False, subplot_kw=subplot_kw or None)
    return fig, (axes[0, 0] if axes.size == 1 else axes.ravel())


def draw_springs(ax, x, edges, fixed=(), color="0.3", lw=0.8, particle_size=6, strain_limit=None,
                 rest_length=None):
    """Draw a 2-D spring system: springs as lines, particles as dots, fixed ones as squares.

    x : (n, 2) positions; edges : (E, 2) int. With ``rest_length`` (E,), springs are coloured
    by strain ``l/L - 1`` (blue compressed, red stretched, limits ±``strain_limit`` or ±5 %).
    Returns the LineCollection.
    """
    x = np.asarray(x)
    segs = x[np.asarray(edges)]
    if rest_length is None:
        lc = LineCollection(segs, colors=color, linewidths=lw, zorder=1)
    else:
        lc = LineCollection(segs, linewidths=lw, zorder=1)
        strain = np.linalg.norm(segs[:, 1] - segs[:, 0], axis=1) / np.maximum(rest_length, 1e-12) - 1
        lim = strain_limit or 0.05
        lc.set_array(strain)
        lc.set_cmap("coolwarm")
        lc.set_clim(-lim, lim)
    ax.add_collection(lc)
    fixed = np.asarray(fixed, dtype=int)
    free = np.setdiff1d(np.arange(len(x)), fixed)
    ax.scatter(*x[free].T, s=particle_size, c="k", zorder=2)
    if fixed.size:
        ax.scatter(*x[fixed].T, s=particle_size * 5, marker="s", c="tab:red", zorder=3)
    ax.set_aspect("equal")
    ax.autoscale_view()
    return lc


def plot_snapshots(ax, xs, edges, indices, fixed=(), cmap="viridis_r", t=None):
    """Overlay the spring system at several frames ``indices`` of ``xs`` (T, n, 2), early
    frames light, late frames dark: a static 'film strip' for readers without video.

    ``t``: optional (T,) times; returns a ScalarMappable of the snapshot times (or frame
    indices) for a colourbar that explains the colours."""
    import matplotlib
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    indices = list(indices)
    when = np.asarray(t)[indices] if t is not None else np.asarray(indices, float)
    lo, hi = float(when[0]), float(when[-1]) if when[-1] > when[0] else float(when[0]) + 1
    cm = matplotlib.colormaps[cmap]
    sub = matplotlib.colors.ListedColormap(cm(np.linspace(0.1, 0.95, 256)))
    norm = Normalize(lo, hi)
    for i, w in zip(indices, when):
        draw_springs(ax, xs[i], edges, fixed=fixed, color=[sub(norm(w))], particle_size=3)
    ax.set_aspect("equal")
    return ScalarMappable(norm=norm, cmap=sub)


def plot_convergence(ax, dts, errors, orders=None):
    """Log–log error against ``dt`` per method (``errors``: dict method -> (len(dts),)).

    The legend gives each measured slope (least-squares in log–log); dotted guides show
    the theoretical ``orders`` (dict method -> p) when given. A method whose errors equal an
    earlier one's (midpoint and Heun on a linear ODE) is drawn dashed with hollow squares and
    labelled so, instead of hiding under it."""
    from physlab.integrators import convergence_order

    dts = np.asarray(dts)
    slopes, drawn = {}, {}
    for m, e in errors.items():
        e = np.asarray(e)
        slopes[m] = convergence_order(dts, e)
        twin = next((p for p, ep in drawn.items() if np.allclose(e, ep, rtol=1e-6, atol=0)), None)
        label = f"{m}: slope {slopes[m]:.2f}"
        if twin is None:
            ax.loglog(dts, e, "o-", color=METHOD_COLORS.get(m), label=label)
        else:  # the same numbers (midpoint = Heun on a linear ODE): keep both visible
            ax.loglog(dts, e, "s--", mfc="none", ms=9, color=METHOD_COLORS.get(m),
                      label=f"{label} (= {twin}: identical here)")
        drawn[m] = e
        if orders and m in orders:
            ax.loglog(dts, e[-1] * (dts / dts[-1]) ** orders[m], ":", color=METHOD_COLORS.get(m), lw=1)
    from matplotlib.ticker import NullFormatter

    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xticks(dts, [f"{d:g}" for d in dts])
    ax.set_xlabel("time step dt (s)")
    ax.set_ylabel("global error at t_end")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    return slopes


def plot_stability_regions(ax, methods, extent=(-4.5, 2.5, -3.5, 3.5), points=None):
    """Shade ``|R(z)| <= 1`` of each method in the complex plane ``z = h λ``.

    ``points``: optional dict label -> complex z to mark (e.g. ``h λ`` of a spring)."""
    from physlab.integrators import stability_function

    re = np.linspace(extent[0], extent[1], 400)
    im = np.linspace(extent[2], extent[3], 400)
    Z = re[None, :] + 1j * im[:, None]
    for m in methods:
        with np.errstate(all="ignore"):
            R = np.abs(stability_function(m, Z))
        color = METHOD_COLORS.get(m)
        ax.contourf(re, im, R <= 1, levels=[0.5, 1.5], colors=[color], alpha=0.15)
        ax.contour(re, im, R, levels=[1.0], colors=[color], linewidths=1.2)
        ax.plot([], [], color=color, label=m)
    for label, z in (points or {}).items():
        ax.plot(z.real, z.imag, "k*", ms=9)
        ax.annotate(label, (z.real, z.imag), textcoords="offset points", xytext=(4, 4), fontsize=8)
    ax.axhline(0, color="0.6", lw=0.5)
    ax.axvline(0, color="0.6", lw=0.5)
    ax.set_xlabel("Re(hλ)")
    ax.set_ylabel("Im(hλ)")
    ax.set_aspect("equal")
    ax.legend(fontsize=7, loc="upper left")


def plot_newton_residuals(ax, residuals, label=None):
    """Residual norm ``|G(z_k)|`` per Newton iteration, log scale."""
    r = np.asarray(residuals, float)
    ax.semilogy(np.arange(len(r)), np.maximum(r, 1e-17), "o-", label=label)
    ax.set_xlabel("Newton iteration k")
    ax.set_ylabel("|G(y_k)|")
    ax.grid(True, which="both", alpha=0.3)
