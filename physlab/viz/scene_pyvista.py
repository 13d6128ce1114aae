"""The PyVista scene of a motion: capsule meshes, checkered ground, red keypose, green
trajectories, lit and framed; rendered offscreen to RGB frames or a strobe image.

:func:`skeleton_meshes` (one pose -> meshes), :func:`render_motion_pyvista` (clip -> frames,
one plotter whose body mesh is updated per frame) and :func:`motion_plotter` (a stroboscopic
:class:`pyvista.Plotter`, for :func:`physlab.viz.view3d.strobe` and the notebook viewer).
PyVista is imported inside the functions (:func:`physlab.viz.offscreen._import_pyvista`), so
importing this module is cheap.
"""
from __future__ import annotations

import numpy as np

from physlab.viz.camera import _VIEW_ANGLE, _camera_position
from physlab.viz.capsules import _HEAD, _check_joints, capsule_arrays, capsule_segments
from physlab.viz.motion_scene import (
    COLORS,
    _frame_indices,
    _ground_extent,
    _ground_height,
    _prepare,
    _runs,
    _strobe_colors,
    _strobe_indices,
)
from physlab.viz.offscreen import _import_pyvista

__all__ = ["motion_plotter", "render_motion_pyvista", "skeleton_meshes"]


def _ground_mesh(pv, extent, height, cell=0.5):
    x0, x1, z0, z1 = extent
    nx, nz = max(1, round((x1 - x0) / cell)), max(1, round((z1 - z0) / cell))
    plane = pv.Plane(center=((x0 + x1) / 2, height, (z0 + z1) / 2), direction=(0, 1, 0),
                     i_size=x1 - x0, j_size=z1 - z0, i_resolution=nx, j_resolution=nz)
    c = plane.cell_centers().points
    checker = ((np.floor(c[:, 0] / cell) + np.floor(c[:, 2] / cell)) % 2).astype(int)
    plane.cell_data["checker"] = checker.astype(np.uint8)
    tiles = np.array([COLORS["ground_light"], COLORS["ground_dark"]])
    plane.cell_data["rgb"] = (255 * tiles[checker]).round().astype(np.uint8)
    return plane


def _polydata(pv, points, normals, faces):
    mesh = pv.PolyData.from_regular_faces(np.ascontiguousarray(points), faces)
    mesh.point_data["Normals"] = np.ascontiguousarray(normals)
    mesh.point_data.active_normals_name = "Normals"
    return mesh


def skeleton_meshes(joints_frame, radius=None, ground="auto"):
    """PyVista meshes of one pose: the capsule-bone human and a checkered ground plane.

    Parameters
    ----------
    joints_frame : (22, 3) float array, metres, y up.
    radius : None (:data:`~physlab.viz.capsules.BONE_RADII`), float or (22,) float array
        (see :func:`~physlab.viz.capsules.capsule_segments`).
    ground : ``"auto"`` (the lowest capsule point, so the human stands on it; with
        HumanML3D data, whose lowest foot joint is at y = 0, that is a few cm below 0), a
        float height (metres) or None (= ``"auto"``).

    Returns
    -------
    dict with ``"body"``: :class:`pyvista.PolyData` of 24 capsules (cell data ``"joint"``:
    the joint each capsule belongs to; point data ``"Normals"``) and ``"ground"``:
    :class:`pyvista.PolyData` plane at the ground height (cell data ``"checker"`` 0 / 1 and
    its colours ``"rgb"``).
    """
    pv = _import_pyvista()
    x = _check_joints(joints_frame, "joints_frame")
    if len(x) != 1:
        raise ValueError(f"joints_frame must be one pose (22, 3), got {np.shape(joints_frame)}")
    a, b, r, joint = capsule_segments(x, radius)
    P, N, faces = capsule_arrays(a[0], b[0], r)
    body = _polydata(pv, P, N, faces)
    body.cell_data["joint"] = np.repeat(joint, len(faces) // len(joint))
    gy = _ground_height(x, radius, ground)
    return {"body": body, "ground": _ground_mesh(pv, _ground_extent(x), gy)}


def _scene_points(x, keypose, trajs):
    """Points the camera must see: joints, head tops, keypose and trajectory points."""
    pts = [x.reshape(-1, 3)]
    u = x[:, 15] - x[:, 12]
    pts.append(x[:, 15] + _HEAD[1] * u / np.maximum(np.linalg.norm(u, axis=-1,
                                                                    keepdims=True), 1e-9))
    if keypose is not None:
        pts.append(keypose)
    pts += [p[np.all(np.isfinite(p), axis=1)] for _, p in trajs]
    return np.concatenate(pts)


def _trajectory_mesh(pv, trajs, tube=0.012, dot=0.022):
    meshes = []
    for _, p in trajs:
        for run in _runs(p):
            if len(run) > 1:
                meshes.append(pv.lines_from_points(run).tube(radius=tube, n_sides=12))
            meshes.append(pv.PolyData(run).glyph(geom=pv.Sphere(radius=dot, theta_resolution=12,
                                                                 phi_resolution=12),
                                                 scale=False, orient=False))
    if not meshes:
        return None
    out = meshes[0].merge(meshes[1:]) if len(meshes) > 1 else meshes[0]
    return out.extract_surface() if not isinstance(out, pv.PolyData) else out


def _new_plotter(pv, size, off_screen):
    p = pv.Plotter(off_screen=off_screen, window_size=list(size))
    p.set_background(COLORS["background"])
    p.enable_anti_aliasing("msaa")       # FXAA is unsupported with EGL / OSMesa
    return p


def _add_static(p, pv, x, keypose, trajs, radius, ground, r_kp=1.03):
    """Ground, keypose (red) and trajectories (green); returns the ground height."""
    gy = _ground_height(x if keypose is None else np.concatenate([x, keypose[None]]), radius,
                        ground)
    pts = [x.reshape(-1, 3)] + ([keypose] if keypose is not None else []) + \
          [p_[np.all(np.isfinite(p_), axis=1)] for _, p_ in trajs]
    plane = _ground_mesh(pv, _ground_extent(np.concatenate(pts)), gy)
    p.add_mesh(plane, scalars="rgb", rgb=True, ambient=0.35, diffuse=0.65, specular=0.0)
    if keypose is not None:
        a, b, r, _ = capsule_segments(keypose, radius)
        P, N, faces = capsule_arrays(a[0], b[0], r * r_kp)
        _add_body(p, _polydata(pv, P, N, faces), COLORS["keypose"])
    tm = _trajectory_mesh(pv, trajs)
    if tm is not None:
        p.add_mesh(tm, color=COLORS["trajectory"], ambient=0.3, diffuse=0.7, specular=0.1,
                   smooth_shading=True)
    return gy


def _add_body(p, mesh, color=None, rgb=False):
    kw = {"scalars": "rgb", "rgb": True} if rgb else {"color": color}
    actor = p.add_mesh(mesh, ambient=0.22, diffuse=0.75, specular=0.25, specular_power=20,
                       smooth_shading=False, **kw)
    actor.prop.interpolation = "phong"        # use the exact capsule normals we supply
    return actor


def render_motion_pyvista(joints, keypose=None, keypose_frame=None, trajectories=None,
                          frames=None, size=(400, 400), camera="iso", off_screen=True,
                          ground="auto", radius=None, progress=False):
    """Render a clip with PyVista as RGB frames: capsule human, red keypose, green trajectories.

    Parameters
    ----------
    joints : (T, 22, 3) float array, metres, y up (ValueError on other shapes or NaN).
    keypose : None or (22, 3) float array, drawn in red in every frame (Sketch2Anim's
        keypose condition); None with ``keypose_frame`` set uses ``joints[keypose_frame]``.
    keypose_frame : None or int, the frame the keypose belongs to (there the body coincides
        with the red keypose, drawn 3 % thicker, so the body shows red).
    trajectories : None or dict joint name (or index) -> (t_r, 3) or (T, 3) float array,
        NaN rows are gaps; drawn as green tubes with a sphere per point.
    frames : None (all), an int (returns one image) or a sequence of frame indices.
    size : (width, height) in pixels.
    camera : ``"front"``, ``"side"``, ``"iso"``, ``"top"``, a (3,) direction from the scene
        to the camera, or ``(position, focal_point, view_up)``; the view is fixed over the
        clip and frames the whole clip.
    off_screen : bool, render without a window (the default; needs no display).
    ground : ``"auto"``, float height or None, see :func:`skeleton_meshes`.
    radius : None, float or (22,) bone radii, see
        :func:`~physlab.viz.capsules.capsule_segments`.
    progress : bool, tqdm progress bar.

    Returns
    -------
    list of (H, W, 3) uint8 arrays (``H, W = size[1], size[0]``), or one array if
    ``frames`` is an int. RuntimeError if PyVista is missing or cannot render.
    """
    x, keypose, keypose_frame, trajs, size, r = _prepare(joints, keypose, keypose_frame,
                                                         trajectories, size, radius)
    idx, single = _frame_indices(frames, len(x))
    pv = _import_pyvista()
    a, b, rs, _ = capsule_segments(x[idx], r)
    P, N, faces = capsule_arrays(a, b, rs)                                    # (F, n, 3)
    p = _new_plotter(pv, size, off_screen)
    try:
        _add_static(p, pv, x, keypose, trajs, r, ground)
        body = _polydata(pv, P[0], N[0], faces)
        _add_body(p, body, COLORS["body"])
        p.camera_position = _camera_position(camera, _scene_points(x, keypose, trajs), size,
                                         pad=1.9 * float(r.max()))
        p.camera.view_angle = _VIEW_ANGLE
        out = []
        it = range(len(idx))
        if progress:
            from tqdm.auto import tqdm

            it = tqdm(it, desc="render", unit="frame")
        for k in it:
            body.points = P[k]
            body.point_data["Normals"] = N[k]
            body.point_data.active_normals_name = "Normals"
            p.render()
            out.append(np.array(p.screenshot(return_img=True)[..., :3], dtype=np.uint8))
    finally:
        p.close()
    return out[0] if single else out


def motion_plotter(joints, keypose=None, keypose_frame=None, trajectories=None, every=5,
                   frames=None, size=(640, 400), camera="iso", off_screen=True, ground="auto",
                   radius=None, offset=None):
    """A :class:`pyvista.Plotter` holding a stroboscopic scene of the clip (for
    :func:`~physlab.viz.view3d.strobe` and the notebook viewer of
    :func:`~physlab.viz.view3d.show_motion`); the caller closes it.

    Ghosts at ``frames`` (default every ``every``-th frame and the last) run from light
    (early) to dark slate (late); the keypose frame is red; trajectories green.
    ``offset`` (3,) metres shifts ghost ``k`` by ``k · offset`` to spread an in-place motion.
    Other parameters as in :func:`render_motion_pyvista`.
    """
    x, keypose, keypose_frame, trajs, size, r = _prepare(joints, keypose, keypose_frame,
                                                         trajectories, size, radius)
    idx = (_strobe_indices(len(x), every, keypose_frame) if frames is None
           else _frame_indices(frames, len(x))[0])
    shift = np.zeros(3) if offset is None else np.asarray(offset, dtype=float)
    if shift.shape != (3,):
        raise ValueError(f"offset must be a (3,) vector in metres, got {offset!r}")
    xs = x[idx] + np.arange(len(idx))[:, None, None] * shift              # (G, 22, 3)
    pv = _import_pyvista()
    a, b, rs, _ = capsule_segments(xs, r)
    P, N, faces = capsule_arrays(a, b, rs)                                # (G, n, 3)
    colors = _strobe_colors(len(idx))
    if keypose_frame is not None:
        colors[np.flatnonzero(idx == keypose_frame)] = COLORS["keypose"]
    n = P.shape[1]
    body = _polydata(pv, P.reshape(-1, 3), N.reshape(-1, 3),
                     (faces[None] + n * np.arange(len(idx))[:, None, None]).reshape(-1, 3))
    body.point_data["rgb"] = np.repeat((255 * colors).round().astype(np.uint8), n, axis=0)
    # a keypose that differs from the red ghost (e.g. a condition the motion missed) is
    # drawn as its own red capsules
    kp = keypose if keypose is not None and (
        keypose_frame is None or not np.allclose(keypose, x[keypose_frame])) else None
    p = _new_plotter(pv, size, off_screen)
    _add_static(p, pv, xs, kp, trajs, r, ground)
    _add_body(p, body, rgb=True)
    p.camera_position = _camera_position(camera, _scene_points(xs, kp, trajs), size,
                                         pad=1.9 * float(r.max()))
    p.camera.view_angle = _VIEW_ANGLE
    return p


def _strobe_pyvista(joints, every, keypose, keypose_frame, trajectories, frames, size, camera,
                    ground, radius, offset):
    """:func:`physlab.viz.view3d.strobe` with PyVista: (H, W, 3) uint8."""
    p = motion_plotter(joints, keypose=keypose, keypose_frame=keypose_frame,
                       trajectories=trajectories, every=every, frames=frames, size=size,
                       camera=camera, off_screen=True, ground=ground, radius=radius,
                       offset=offset)
    try:
        p.render()
        return np.array(p.screenshot(return_img=True)[..., :3], dtype=np.uint8)
    finally:
        p.close()
