"""The matplotlib 3-D scene of a motion, the fallback when PyVista cannot render offscreen.

Bones are lines whose width follows :data:`~physlab.viz.capsules.BONE_RADII`, the head a dot,
the keypose red, trajectories green, the ground a grey square; y (up) is drawn vertically
(data ``(x, y, z)`` -> axes ``(x, -z, y)``, :func:`_to_mpl`) with equal aspect.
:func:`plot_motion_matplotlib` gives a :class:`~matplotlib.figure.Figure` (no pyplot state);
the private renderers rasterise it with Agg for :func:`physlab.viz.view3d.render_motion` and
:func:`physlab.viz.view3d.strobe`. matplotlib is imported inside the functions.
"""
from __future__ import annotations

import numpy as np

from physlab.motion.skeleton import PARENTS
from physlab.viz.camera import _view_direction
from physlab.viz.capsules import _J, _check_joints
from physlab.viz.motion_scene import (
    COLORS,
    _check_keypose,
    _frame_indices,
    _ground_extent,
    _ground_height,
    _prepare,
    _runs,
    _strobe_colors,
    _strobe_indices,
)

__all__ = ["plot_motion_matplotlib"]


def _to_mpl(v):
    """Data (x, y up, z) -> matplotlib axes (X, Y, Z up) = (x, -z, y): right-handed."""
    v = np.asarray(v, dtype=float)
    return np.stack([v[..., 0], -v[..., 2], v[..., 1]], axis=-1)


def _bone_segments(pose):
    kids = np.arange(1, _J)
    return _to_mpl(np.stack([pose[PARENTS[kids]], pose[kids]], axis=1))       # (21, 2, 3)


def _mpl_scene(x, frames, keypose, keypose_frame, trajs, size, camera, ground, r, ax=None,
               offset=None, lw_scale=90.0, frame_all=False):
    """Draw the matplotlib scene; returns (fig, ax, set_pose(pose) or None). With
    ``frame_all`` the axes cover the whole clip ``x`` (animation), else the drawn poses."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import FuncFormatter, MaxNLocator
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    if ax is None:
        fig = Figure(figsize=(size[0] / 100, size[1] / 100), dpi=100)
        ax = fig.add_axes((0, 0, 1, 1), projection="3d")
    else:
        fig = ax.get_figure()
    shift = np.zeros(3) if offset is None else np.asarray(offset, dtype=float)
    if shift.shape != (3,):
        raise ValueError(f"offset must be a (3,) vector in metres, got {offset!r}")
    single = len(frames) == 1
    xs = x[frames] + np.arange(len(frames))[:, None, None] * shift
    lw = lw_scale * r[1:] * min(size) / 400
    colors = _strobe_colors(len(frames)) if not single else np.array([COLORS["body"]]) * 0.75
    set_pose = None
    for k, t in enumerate(frames):
        c = COLORS["keypose"] if t == keypose_frame else colors[k]
        lc = Line3DCollection(_bone_segments(xs[k]), colors=[c], linewidths=lw,
                              capstyle="round", joinstyle="round")
        ax.add_collection3d(lc)
        head = _to_mpl(xs[k, 15] + 0.07 * (xs[k, 15] - xs[k, 12])
                       / max(np.linalg.norm(xs[k, 15] - xs[k, 12]), 1e-9))
        hd = ax.scatter(*head, s=(lw_scale * 1.9 * r[15] * min(size) / 400) ** 2, color=[c],
                        depthshade=False)
        if single:
            def set_pose(pose, lc=lc, hd=hd, default=c, keyed=None):
                lc.set_segments(_bone_segments(pose))
                u = pose[15] - pose[12]
                hd._offsets3d = tuple(np.atleast_1d(v) for v in _to_mpl(
                    pose[15] + 0.07 * u / max(np.linalg.norm(u), 1e-9)))
                col = COLORS["keypose"] if keyed else default
                lc.set_color([col])
                hd.set_color([col])
    extra = [xs.reshape(-1, 3)] + ([x.reshape(-1, 3)] if frame_all else [])
    if keypose is not None and (keypose_frame is None or keypose_frame not in frames or single):
        ax.add_collection3d(Line3DCollection(_bone_segments(keypose), colors=[COLORS["keypose"]],
                                             linewidths=lw * 1.05, alpha=0.85))
        extra.append(keypose[None])
    for _, p in trajs:
        for run in _runs(p):
            m = _to_mpl(run)
            ax.plot(m[:, 0], m[:, 1], m[:, 2], color=COLORS["trajectory"], lw=2)
            ax.scatter(m[:, 0], m[:, 1], m[:, 2], color=[COLORS["trajectory"]], s=10,
                       depthshade=False)
        extra.append(p[np.all(np.isfinite(p), axis=1)])
    pts = np.concatenate([e.reshape(-1, 3) for e in extra])
    gy = _ground_height(np.concatenate([x, xs]), r, ground)
    x0, x1, z0, z1 = _ground_extent(pts, margin=0.4)
    quad = _to_mpl(np.array([[x0, gy, z0], [x1, gy, z0], [x1, gy, z1], [x0, gy, z1]]))
    ax.add_collection3d(Poly3DCollection([quad], facecolors=[COLORS["ground_dark"]],
                                         edgecolors="0.6", alpha=0.5))
    # equal aspect: limits = the scene's box (ground included), box aspect = its extents
    lo = np.minimum(pts.min(0) - [0, 0, 0], [x0, gy, z0])
    hi = np.maximum(pts.max(0) + [0, 0.15, 0], [x1, gy, z1])
    lo_m, hi_m = _to_mpl(lo), _to_mpl(hi)
    lo_m, hi_m = np.minimum(lo_m, hi_m), np.maximum(lo_m, hi_m)
    ax.set_xlim(lo_m[0], hi_m[0])
    ax.set_ylim(lo_m[1], hi_m[1])
    ax.set_zlim(lo_m[2], hi_m[2])
    ax.set_box_aspect(tuple(hi_m - lo_m))
    d = _to_mpl(_view_direction(camera) if isinstance(camera, str) or np.shape(camera) == (3,)
                else np.subtract(*np.asarray(camera, float)[:2]))
    ax.view_init(elev=np.degrees(np.arctan2(d[2], np.hypot(d[0], d[1]))),
                 azim=np.degrees(np.arctan2(d[1], d[0])))
    for axis, label in ((ax.xaxis, "x (m)"), (ax.yaxis, "z (m)"), (ax.zaxis, "y up (m)")):
        axis.set_major_locator(MaxNLocator(4))
        axis.set_tick_params(labelsize=6, pad=0)
        axis.set_label_text(label, fontsize=7)
        axis.labelpad = -4
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{-v + 0.0:g}"))  # shows z
    return fig, ax, set_pose


def plot_motion_matplotlib(joints, frames=None, keypose=None, keypose_frame=None,
                           trajectories=None, every=None, size=(400, 400), camera="iso",
                           ground="auto", radius=None, ax=None, offset=None):
    """Matplotlib 3-D figure of a clip (the fallback when PyVista cannot render).

    y (up) is drawn vertically: data ``(x, y, z)`` go to the axes as ``(x, -z, y)`` (a
    right-handed map; the depth axis is labelled with the true z). Aspect is equal. Bones are
    lines whose width follows :data:`~physlab.viz.capsules.BONE_RADII`; the keypose is red,
    trajectories green, the ground a grey square.

    Parameters
    ----------
    joints : (T, 22, 3) or (22, 3) float array, metres.
    frames : None (a strobe of every ``every``-th frame; default ``every = ceil(T / 8)``),
        an int (one pose) or a sequence of frame indices (ghosted light -> dark).
    keypose, keypose_frame, trajectories, camera, ground, radius, offset : as in
        :func:`~physlab.viz.scene_pyvista.motion_plotter` (``camera`` as a direction or name
        sets elevation / azimuth).
    size : (width, height) in pixels at 100 dpi (ignored when ``ax`` is given).
    ax : None or an existing 3-D :class:`~mpl_toolkits.mplot3d.axes3d.Axes3D`.

    Returns
    -------
    :class:`matplotlib.figure.Figure` (no pyplot state).
    """
    x, keypose, keypose_frame, trajs, size, r = _prepare(joints, keypose, keypose_frame,
                                                         trajectories, size, radius)
    if frames is None:
        every = int(np.ceil(len(x) / 8)) if every is None else every
        idx = _strobe_indices(len(x), every, keypose_frame)
    else:
        idx = _frame_indices(frames, len(x))[0]
    fig, _, _ = _mpl_scene(x, idx, keypose, keypose_frame, trajs, size, camera, ground, r, ax,
                           offset)
    return fig


def _figure_rgb(fig):
    """Rasterise a Figure with Agg: (H, W, 3) uint8."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.array(canvas.buffer_rgba())[..., :3]


def _render_motion_matplotlib(joints, keypose, keypose_frame, trajectories, frames, size,
                              camera, ground, radius):
    """:func:`physlab.viz.view3d.render_motion` with matplotlib: one figure whose pose is
    updated per frame; list of (H, W, 3) uint8, or one array if ``frames`` is an int."""
    x, keypose, keypose_frame, trajs, size, r = _prepare(joints, keypose, keypose_frame,
                                                         trajectories, size, radius)
    idx, single = _frame_indices(frames, len(x))
    fig, _, set_pose = _mpl_scene(x, idx[:1], keypose, keypose_frame, trajs, size, camera,
                                  ground, r, frame_all=True)
    out = []
    for t in idx:
        set_pose(x[t], keyed=(t == keypose_frame))
        out.append(_figure_rgb(fig))
    return out[0] if single else out


def _strobe_matplotlib(joints, every, keypose, keypose_frame, trajectories, frames, size, camera,
                       ground, radius, offset):
    """:func:`physlab.viz.view3d.strobe` with matplotlib: (H, W, 3) uint8."""
    x = _check_joints(joints)
    kf = _check_keypose(x, keypose, keypose_frame)[1]
    idx = (_strobe_indices(len(x), every, kf) if frames is None
           else _frame_indices(frames, len(x))[0])
    fig = plot_motion_matplotlib(x, frames=idx, keypose=keypose, keypose_frame=keypose_frame,
                                 trajectories=trajectories, size=size, camera=camera,
                                 ground=ground, radius=radius, offset=offset)
    return _figure_rgb(fig)
