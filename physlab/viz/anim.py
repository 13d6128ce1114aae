"""Frames -> inline animations for notebooks (HTML5 video or JavaScript) and GIF files."""
from __future__ import annotations

import matplotlib
import numpy as np
from matplotlib.animation import FuncAnimation
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

__all__ = ["animate_springs", "to_html", "save_gif"]


def _ffmpeg_exe():
    """Path of the ffmpeg binary shipped with imageio-ffmpeg, or None."""
    try:
        import imageio_ffmpeg

        return imageio_ffmpeg.get_ffmpeg_exe()
    except Exception:  # no bundled ffmpeg: callers fall back to a JavaScript player
        return None


def to_html(anim, fmt="video"):
    """HTML for a matplotlib animation: ``"video"`` (H.264 via the ffmpeg shipped with
    imageio-ffmpeg; small) or ``"jshtml"`` (PNG frames + JavaScript player; no ffmpeg)."""
    import matplotlib

    exe = _ffmpeg_exe() if fmt == "video" else None
    if exe:
        # kbit/s: small notebooks; settings only for this call (no global rcParams change)
        with matplotlib.rc_context({"animation.bitrate": 300, "animation.ffmpeg_path": exe}):
            return anim.to_html5_video()
    return anim.to_jshtml()


def animate_springs(xs, edges, fixed=(), t=None, fps=30, max_frames=90, limits=None,
                    size=(4.0, 3.2), ground=None, fmt="video", html=True, unit="m"):
    """Animate a 2-D spring system trajectory ``xs`` (T, n, 2); axes labelled in ``unit``.

    Frames are subsampled to at most ``max_frames``; playback at ``fps``. Returns an
    :class:`IPython.display.HTML` object (``html=True``) or the FuncAnimation.
    """
    xs = np.asarray(xs)
    edges = np.asarray(edges)
    idx = np.unique(np.linspace(0, len(xs) - 1, min(max_frames, len(xs))).round().astype(int))
    fig = Figure(figsize=size, layout="constrained")
    ax = fig.subplots()
    if limits is None:
        lo, hi = xs[idx].min((0, 1)), xs[idx].max((0, 1))
        pad = 0.05 * (hi - lo).max() + 1e-9
        limits = (lo[0] - pad, hi[0] + pad, lo[1] - pad, hi[1] + pad)
    ax.set_xlim(limits[0], limits[1])
    ax.set_ylim(limits[2], limits[3])
    ax.set_aspect("equal")
    ax.set_xlabel(f"x ({unit})")
    ax.set_ylabel(f"y ({unit})")
    if ground is not None:
        ax.axhspan(limits[2], ground, color="0.85", zorder=0)
    lc = LineCollection(xs[0][edges], colors="0.3", linewidths=0.8)
    ax.add_collection(lc)
    fixed = np.asarray(fixed, dtype=int)
    pts = ax.scatter(*xs[0].T, s=5, c="k")
    if fixed.size:
        ax.scatter(*xs[0][fixed].T, s=25, marker="s", c="tab:red")
    title = ax.set_title("")

    def update(k):
        x = xs[idx[k]]
        lc.set_segments(x[edges])
        pts.set_offsets(x)
        if t is not None:
            title.set_text(f"t = {t[idx[k]]:.2f} s")
        return lc, pts, title

    # Lay the figure out once, with the first frame's title in place, then drop the layout
    # engine: every frame keeps the same axes, and saving a frame no longer runs the layout and
    # a dry draw first (with them, 60 % of the animation's time). None means no engine only
    # while the rcParams ask for none.
    update(0)
    fig.draw_without_rendering()
    with matplotlib.rc_context({"figure.autolayout": False,
                                "figure.constrained_layout.use": False}):
        fig.set_layout_engine(None)

    anim = FuncAnimation(fig, update, frames=len(idx), interval=1000 / fps, blit=False)
    if not html:
        return anim
    from IPython.display import HTML

    return HTML(to_html(anim, fmt))


def save_gif(frames, path, fps=20):
    """Deprecated: use :func:`physlab.render.frames_to_gif` (the one home of frames → GIF /
    MP4 / HTML, atomic and validated). Kept for one release; warns."""
    import warnings

    from physlab.render import frames_to_gif

    warnings.warn("physlab.viz.anim.save_gif moved to physlab.render.frames_to_gif; the old "
                  "name goes in the next release", DeprecationWarning, stacklevel=2)
    return frames_to_gif(frames, path, fps=fps)
