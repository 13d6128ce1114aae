"""Figures for the inbetweening lessons and evaluation (matplotlib, no pyplot state)."""
from __future__ import annotations

import numpy as np

from physlab.image import over_white  # noqa: F401 - part of this module's API

from ..viz.plots import new_figure

__all__ = ["over_white", "draw_skeleton", "draw_mesh", "plot_filmstrip", "plot_image_matrix",
           "plot_path", "contact_sheet"]


def draw_skeleton(ax, skeleton, color="tab:red", lw=1.5, ms=3, handles=False):
    """Bones as lines and joints as dots (pixels, y down); bone midpoints too if ``handles``."""
    for p, c in skeleton.bones:
        ax.plot(*skeleton.xy[[p, c]].T, color=color, lw=lw, solid_capstyle="round")
    pts = skeleton.handles() if handles else skeleton.xy
    ax.plot(*pts.T, "o", color=color, ms=ms, mec="white", mew=0.5)


def draw_mesh(ax, x, tris, values=None, cmap="Reds", vmin=None, vmax=None, lw=0.3, color="0.2"):
    """Triangle mesh (pixels, y down), optionally with per-triangle ``values`` as colours."""
    if values is not None:
        art = ax.tripcolor(x[:, 0], x[:, 1], tris, facecolors=values, cmap=cmap, vmin=vmin,
                           vmax=vmax, edgecolors=color, linewidth=lw)
    else:
        art = ax.triplot(x[:, 0], x[:, 1], tris, color=color, lw=lw)[0]
    ax.set_aspect("equal")
    if not ax.yaxis_inverted():
        ax.invert_yaxis()
    return art


def plot_filmstrip(frames, labels=None, skeletons=None, width=1.3, title=None):
    """One row of frames (n, H, W, C) as a Figure; ``labels`` under each, skeletons on top."""
    n = len(frames)
    H, W = np.asarray(frames[0]).shape[:2]
    fig, axes = new_figure(ncols=n, width=width, height=width * H / W + 0.25)
    axes = np.atleast_1d(axes)
    for i, ax in enumerate(axes):
        ax.imshow(over_white(frames[i]), interpolation="antialiased")
        if skeletons is not None:
            draw_skeleton(ax, skeletons[i], lw=0.8, ms=1.5)
            ax.set_xlim(-0.5, W - 0.5)
            ax.set_ylim(H - 0.5, -0.5)
        ax.set_xticks([])
        ax.set_yticks([])
        if labels is not None:
            ax.set_xlabel(labels[i], fontsize=7)
    if title:
        fig.suptitle(title, fontsize=9)
    return fig


def plot_image_matrix(images, alphas, t, path=None, diagonal=None, every=1, width=0.75):
    """The image matrix I(α, t) as a grid of thumbnails (rows t, columns α), Fig. 9a.

    Parameters
    ----------
    images : (n_t, n_α, H, W, C) images.
    alphas : (n_α,), t : (n_t,).
    path, diagonal : optional (n_t,) column indices to outline (green / red).
    every : show every ``every``-th α column (the path's columns are always shown).
    """
    n_t, n_a = images.shape[:2]
    cols = set(range(0, n_a, every)) | {n_a - 1}
    for p in (path, diagonal):
        if p is not None:
            cols |= set(int(k) for k in p)
    cols = sorted(cols)
    H, W = images.shape[2:4]
    fig, axes = new_figure(ncols=len(cols), nrows=n_t, width=width, height=width * H / W)
    axes = np.asarray(axes).reshape(n_t, len(cols))
    for i in range(n_t):
        for j, k in enumerate(cols):
            ax = axes[i, j]
            ax.imshow(over_white(images[i, k]))
            ax.set_xticks([])
            ax.set_yticks([])
            for p, colr in ((diagonal, "tab:red"), (path, "tab:green")):
                if p is not None and int(p[i]) == k:
                    for s in ax.spines.values():
                        s.set_edgecolor(colr)
                        s.set_linewidth(2.5)
            if i == n_t - 1:
                ax.set_xlabel(f"α={alphas[k]:.3g}", fontsize=7)
            if j == 0:
                ax.set_ylabel(f"t={t[i]:.3g}", fontsize=8)
    return fig


def plot_path(ax, costs, path, diagonal=None, Q=None):
    """Vertex costs as an image (rows t, columns α) with the chosen path and the diagonal."""
    V = np.asarray(costs.vertex)
    n_t, n_a = V.shape
    im = ax.imshow(V, aspect="auto", cmap="viridis", origin="upper",
                   extent=(-0.5 / (n_a - 1), 1 + 0.5 / (n_a - 1), n_t - 0.5, -0.5))
    rows = np.arange(n_t)
    if diagonal is not None:
        ax.plot(diagonal.alphas, rows, "o--", color="tab:red", ms=3, label="diagonal α = t")
    ax.plot(path.alphas, rows, "o-", color="tab:green", ms=3, label="optimal path")
    ax.set_xlabel("α (0 = texture of key 0, 1 = key 1)")
    ax.set_ylabel("frame")
    ax.legend(loc="lower left", fontsize=7)
    if Q is not None:
        tw = ax.twiny()
        tw.plot(np.asarray(Q) / max(np.max(Q), 1e-30), rows, color="white", lw=1, alpha=0.8)
        tw.set_xlim(0, 1)
        tw.set_xlabel("Q(t) / max Q (white)", fontsize=7)
    return im


def contact_sheet(frames, path=None, skeletons=None, labels=None, title=None, width=1.3):
    """Filmstrip Figure of a sequence; written to ``path`` (PNG) when given."""
    fig = plot_filmstrip(frames, labels=labels, skeletons=skeletons, width=width, title=title)
    if path is not None:
        from .._io import atomic_write

        atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=90), suffix=".png")
    return fig
