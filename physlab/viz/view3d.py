"""3-D views of 22-joint motions: a capsule-bone human rendered offscreen with PyVista.

Joint arrays are ``(T, 22, 3)`` in metres, y up, in :data:`~physlab.motion.skeleton.JOINT_NAMES`
order (HumanML3D / Sketch2Anim). Every bone is drawn as a capsule (a cylinder closed by two
hemispheres) whose radius depends on the body part (:data:`BONE_RADII`: thick torso and
thighs, thin forearms), plus a head and two hands — the "default capsule-bone human model"
of Sketch2Anim (Sec. 3, "Output"). As in the paper's figures (Fig. 1, Fig. A1) the *keypose*
is drawn in red and *joint trajectories* in green. A checkered ground plane sits under the
feet; by default the camera frames the whole clip from a 3/4 ("iso") view.

Backends
    * PyVista / VTK, offscreen. On Linux without ``$DISPLAY`` VTK >= 9.4 renders through EGL
      (Mesa's llvmpipe when there is no GPU); this module sets
      ``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow`` in that case (only if unset) so VTK does
      not try X first. Xvfb is not needed (``pyvista.start_xvfb`` is gone from PyVista 0.49);
      OSMesa works too when ``libOSMesa`` is installed
      (``VTK_DEFAULT_OPENGL_WINDOW=vtkOSOpenGLRenderWindow``).
    * matplotlib 3-D axes, the fallback: ``backend="auto"`` probes once per process (in a
      subprocess, since a broken OpenGL stack can abort the interpreter) whether PyVista can
      render offscreen, and otherwise uses matplotlib with a single warning.

PyVista (and VTK) are imported inside the functions, so importing this module is cheap.

Main functions: :func:`skeleton_meshes` (one pose -> meshes), :func:`render_motion_pyvista`
and :func:`render_motion` (clip -> RGB frames), :func:`strobe` (several frames ghosted in one
image, the usual way papers show a motion), :func:`plot_motion_matplotlib` (-> Figure),
:func:`show_motion` (notebooks), :func:`motion_to_gif` / :func:`motion_to_mp4`.
"""
from __future__ import annotations

import functools
import os
import re
import signal
import subprocess
import sys
import warnings

import numpy as np

from physlab.motion.skeleton import JOINT_NAMES, PARENTS, joint_index

__all__ = [
    "BONE_RADII",
    "CAMERAS",
    "COLORS",
    "capsule_arrays",
    "capsule_segments",
    "motion_plotter",
    "motion_to_gif",
    "motion_to_mp4",
    "plot_motion_matplotlib",
    "pyvista_offscreen_available",
    "render_motion",
    "render_motion_pyvista",
    "resolve_backend",
    "show_motion",
    "skeleton_meshes",
    "strobe",
]

_J = len(JOINT_NAMES)

#: (22,) float, capsule radius (metres) of the bone ending at each joint (row 0, the pelvis,
#: has no bone). Torso and thighs thick, forearms and feet thin (adult proportions).
BONE_RADII = np.array([
    0.0,                     # pelvis
    0.075, 0.075,            # pelvis -> hips
    0.095,                   # pelvis -> spine1
    0.065, 0.065,            # thighs
    0.10,                    # spine1 -> spine2
    0.048, 0.048,            # shins
    0.105,                   # spine2 -> spine3 (chest)
    0.036, 0.036,            # feet (ankle -> toe base)
    0.05,                    # spine3 -> neck
    0.06, 0.06,              # spine3 -> collars
    0.045,                   # neck -> head
    0.052, 0.052,            # collar -> shoulder
    0.044, 0.044,            # upper arms
    0.036, 0.036,            # forearms
])
BONE_RADII.setflags(write=False)

#: RGB colours in [0, 1]: Sketch2Anim draws the keypose in red and trajectories in green.
COLORS = {
    "body": (0.80, 0.82, 0.86),
    "keypose": (1.0, 0.0, 0.0),
    "trajectory": (0.0, 0.85, 0.0),
    "ground_light": (0.93, 0.93, 0.93),
    "ground_dark": (0.80, 0.80, 0.80),
    "background": (1.0, 1.0, 1.0),
    "strobe_first": (0.90, 0.92, 0.95),
    "strobe_last": (0.38, 0.46, 0.60),
}

#: Named views: direction from the focal point to the camera (the character faces +z, its
#: left is +x). "side" looks at its right side, so forward (+z) points right on screen.
CAMERAS = {
    "front": (0.0, 0.15, 1.0),
    "side": (-1.0, 0.15, 0.0),
    "iso": (-1.0, 0.55, 1.25),
    "top": (0.0, 1.0, 1e-3),
}

_HEAD = (0.02, 0.11, 1.9)      # head capsule: from head + a·u to head + b·u, radius k·r_neck
_HAND = (0.0, 0.075, 1.0)      # hand capsule: continues the forearm, radius k·r_forearm
_VIEW_ANGLE = 30.0             # degrees, VTK's default vertical field of view


# ----------------------------------------------------------------------------- validation


def _check_joints(joints, name="joints"):
    x = np.asarray(joints, dtype=float)
    if x.ndim == 2:
        x = x[None]
    if x.ndim != 3 or x.shape[1:] != (_J, 3) or len(x) == 0:
        raise ValueError(f"{name} must have shape (T, {_J}, 3) or ({_J}, 3) (metres, y up), "
                         f"got {np.shape(joints)}")
    if not np.all(np.isfinite(x)):
        t, j = np.argwhere(~np.isfinite(x))[0][:2]
        raise ValueError(f"{name} contains NaN or inf (first at frame {t}, joint "
                         f"{JOINT_NAMES[j]}); clean or drop those frames first")
    return x


def _check_keypose(joints, keypose, keypose_frame):
    """(22, 3) keypose or None; ``keypose=None`` with a frame takes ``joints[keypose_frame]``."""
    T = len(joints)
    if keypose_frame is not None:
        if not float(keypose_frame).is_integer() or not -T <= int(keypose_frame) < T:
            raise ValueError(f"keypose_frame must be an integer frame index in 0..{T - 1}, got "
                             f"{keypose_frame}")
        keypose_frame = int(keypose_frame) % T
    if keypose is None:
        return (None if keypose_frame is None else joints[keypose_frame]), keypose_frame
    k = np.asarray(keypose, dtype=float)
    if k.shape != (_J, 3):
        raise ValueError(f"keypose must have shape ({_J}, 3), got {k.shape}")
    if not np.all(np.isfinite(k)):
        raise ValueError("keypose contains NaN or inf; give all 22 joints")
    return k, keypose_frame


def _check_trajectories(trajectories):
    """dict name/index -> (n, 3) float with NaN rows allowed -> list of (joint, points)."""
    if trajectories is None:
        return []
    if not isinstance(trajectories, dict):
        raise TypeError(f"trajectories must be a dict joint name -> (t_r, 3) array, got "
                         f"{type(trajectories).__name__}")
    out = []
    for key, pts in trajectories.items():
        if isinstance(key, str):
            j = joint_index(key)
        elif isinstance(key, (int, np.integer)) and 0 <= key < _J:
            j = int(key)
        else:
            raise ValueError(f"unknown trajectory joint {key!r}; use a name of {JOINT_NAMES} "
                             f"or an index 0..{_J - 1}")
        p = np.asarray(pts, dtype=float)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"trajectory of {JOINT_NAMES[j]} must have shape (t_r, 3) or "
                             f"(T, 3) with NaN rows for gaps, got {p.shape}")
        if np.any(np.isinf(p)):
            raise ValueError(f"trajectory of {JOINT_NAMES[j]} contains inf")
        if not np.any(np.all(np.isfinite(p), axis=1)):
            raise ValueError(f"trajectory of {JOINT_NAMES[j]} has no finite point")
        out.append((j, p))
    return out


def _runs(p):
    """Consecutive finite rows of ``p`` (n, 3): list of (m, 3) arrays (NaN rows split)."""
    ok = np.all(np.isfinite(p), axis=1)
    edges = np.flatnonzero(np.diff(np.r_[0, ok.astype(int), 0]))
    return [p[a:b] for a, b in zip(edges[::2], edges[1::2])]


def _check_size(size):
    w, h = (int(v) for v in size)
    if w < 16 or h < 16:
        raise ValueError(f"size must be (width, height) in pixels, each >= 16, got {size}")
    return w, h


def _radii(radius):
    if radius is None:
        return np.array(BONE_RADII)
    r = np.asarray(radius, dtype=float)
    if r.ndim == 0:
        r = np.full(_J, float(r))
    if r.shape != (_J,) or np.any(r[1:] <= 0) or not np.all(np.isfinite(r)):
        raise ValueError(f"radius must be None, a float > 0 or a ({_J},) array of bone radii "
                         f"(> 0 for joints 1..21), got {radius!r}")
    return r


# ----------------------------------------------------------------------------- capsule geometry


def capsule_segments(joints, radius=None):
    """The capsules of the capsule-bone human: 21 bones, a head and two hands.

    Parameters
    ----------
    joints : (T, 22, 3) or (22, 3) float array, metres.
    radius : None (:data:`BONE_RADII`), float (all bones) or (22,) float array (bone ending
        at each joint).

    Returns
    -------
    a, b : (T, 24, 3) float arrays, capsule axis end points (bones in child-joint order
        1..21, then head, left hand, right hand); r : (24,) float radii; joint : (24,) int,
        the joint each capsule belongs to (child joint of a bone, 15 head, 20 / 21 hands).
    """
    x = _check_joints(joints)
    r = _radii(radius)
    kids = np.arange(1, _J)
    a, b = [x[:, PARENTS[kids]]], [x[:, kids]]
    u = x[:, 15] - x[:, 12]
    u = u / np.maximum(np.linalg.norm(u, axis=-1, keepdims=True), 1e-9)   # neck -> head
    a.append(x[:, 15:16] + _HEAD[0] * u[:, None])
    b.append(x[:, 15:16] + _HEAD[1] * u[:, None])
    f = x[:, [20, 21]] - x[:, [18, 19]]
    f = f / np.maximum(np.linalg.norm(f, axis=-1, keepdims=True), 1e-9)    # forearm directions
    a.append(x[:, [20, 21]] + _HAND[0] * f)
    b.append(x[:, [20, 21]] + _HAND[1] * f)
    radii = np.r_[r[1:], _HEAD[2] * r[15], _HAND[2] * r[20], _HAND[2] * r[21]]
    joint = np.r_[kids, 15, 20, 21]
    return np.concatenate(a, axis=1), np.concatenate(b, axis=1), radii, joint


@functools.lru_cache(maxsize=4)
def _capsule_template(n_theta=16, n_phi=5):
    """Unit capsule: radial part ``A`` (n, 3) (= the outward normal), axial flag ``s`` (n,)
    (0 bottom, 1 top) and triangles (m, 3); a capsule of radius r from 0 to L·ẑ has points
    ``r A + L s ẑ``."""
    th = 2 * np.pi * np.arange(n_theta) / n_theta
    phis = np.r_[-np.pi / 2 + np.pi / 2 * np.arange(1, n_phi + 1) / n_phi,   # bottom, to 0
                 np.pi / 2 * np.arange(0, n_phi) / n_phi]                    # top, from 0
    s_ring = np.r_[np.zeros(n_phi), np.ones(n_phi)]
    ring = np.stack([np.cos(phis)[:, None] * np.cos(th), np.cos(phis)[:, None] * np.sin(th),
                     np.sin(phis)[:, None] * np.ones_like(th)], axis=-1)    # (2 n_phi, n_theta, 3)
    A = np.concatenate([[[0, 0, -1.0]], ring.reshape(-1, 3), [[0, 0, 1.0]]])
    s = np.r_[0.0, np.repeat(s_ring, n_theta), 1.0]
    n_r = 2 * n_phi
    idx = 1 + np.arange(n_r * n_theta).reshape(n_r, n_theta)
    nxt = np.roll(idx, -1, axis=1)
    bottom = np.stack([np.zeros(n_theta, int), nxt[0], idx[0]], axis=1)
    top = np.stack([np.full(n_theta, len(A) - 1), idx[-1], nxt[-1]], axis=1)
    q0, q1, q2, q3 = idx[:-1], nxt[:-1], nxt[1:], idx[1:]                    # quads between rings
    quads = np.concatenate([np.stack([q0, q1, q2], -1).reshape(-1, 3),
                            np.stack([q0, q2, q3], -1).reshape(-1, 3)])
    tris = np.concatenate([bottom, quads, top])
    for arr in (A, s, tris):
        arr.setflags(write=False)
    return A, s, tris


def _frames_from_axis(u):
    """(..., 3, 3) rotations whose third column is the unit vector ``u`` (..., 3)."""
    helper = np.where(np.abs(u[..., :1]) < 0.9, [1.0, 0, 0], [0, 1.0, 0])
    e1 = np.cross(helper, u)
    e1 /= np.maximum(np.linalg.norm(e1, axis=-1, keepdims=True), 1e-12)
    e2 = np.cross(u, e1)
    return np.stack([e1, e2, u], axis=-1)


def capsule_arrays(a, b, r, n_theta=16, n_phi=5):
    """Triangle meshes of capsules from ``a`` to ``b``, vectorised over frames and capsules.

    Parameters
    ----------
    a, b : (..., S, 3) float arrays, axis end points (metres); r : (S,) float radii.
    n_theta, n_phi : segments around the axis and per hemisphere.

    Returns
    -------
    points : (..., S·n, 3) float; normals : (..., S·n, 3) float unit outward normals;
    tris : (S·m, 3) int triangles (shared by all frames).
    """
    A, s, tris = _capsule_template(n_theta, n_phi)
    a, b = np.asarray(a, float), np.asarray(b, float)
    r = np.asarray(r, float)
    d = b - a
    L = np.linalg.norm(d, axis=-1)                                            # (..., S)
    u = np.where(L[..., None] > 1e-9, d / np.maximum(L, 1e-12)[..., None], [0, 1.0, 0])
    Q = _frames_from_axis(u)                                                  # (..., S, 3, 3)
    normals = np.einsum("...ij,nj->...ni", Q, A)                              # (..., S, n, 3)
    points = (a[..., None, :] + r[:, None, None] * normals
              + (L[..., None] * s)[..., None] * u[..., None, :])              # r A + L s u
    S, n = r.shape[0], len(A)
    faces = (tris[None] + n * np.arange(S)[:, None, None]).reshape(-1, 3)
    shape = points.shape[:-3] + (S * n, 3)
    return points.reshape(shape), normals.reshape(shape), faces


def _ground_height(x, radius, ground):
    """``"auto"`` / None: the lowest capsule point over the clip ``x`` (T, 22, 3), so the
    capsule human stands on the plane; else ``float(ground)``."""
    if ground is None or (isinstance(ground, str) and ground == "auto"):
        a, b, r, _ = capsule_segments(x, radius)
        return float((np.minimum(a[..., 1], b[..., 1]) - r).min())
    if isinstance(ground, str) or not np.isfinite(float(ground)):
        raise ValueError(f"ground must be 'auto', None or a height in metres, got {ground!r}")
    return float(ground)


def _ground_extent(points, cell=0.5, margin=0.75):
    """Square-snapped xz extent ``(x0, x1, z0, z1)`` covering ``points`` (..., 3)."""
    p = np.asarray(points).reshape(-1, 3)
    lo = np.floor((p[:, [0, 2]].min(0) - margin) / cell) * cell
    hi = np.ceil((p[:, [0, 2]].max(0) + margin) / cell) * cell
    return lo[0], hi[0], lo[1], hi[1]


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
    radius : None (:data:`BONE_RADII`), float or (22,) float array (see
        :func:`capsule_segments`).
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


# ----------------------------------------------------------------------------- backends


def _headless_linux():
    return (sys.platform.startswith("linux") and not os.environ.get("DISPLAY")
            and not os.environ.get("WAYLAND_DISPLAY"))


def _import_pyvista():
    """Import PyVista; on headless Linux prefer VTK's EGL window (only if the user has not
    chosen one via ``VTK_DEFAULT_OPENGL_WINDOW``)."""
    if _headless_linux():
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    try:
        import pyvista
    except ImportError as e:
        raise RuntimeError(f"pyvista is not installed ({e}); pip install pyvista, or use "
                           f"backend='matplotlib'") from None
    return pyvista


_PROBE = """
import os, sys
if sys.platform.startswith("linux") and not os.environ.get("DISPLAY") \\
        and not os.environ.get("WAYLAND_DISPLAY"):
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
import pyvista as pv
p = pv.Plotter(off_screen=True, window_size=(32, 32))
p.set_background("white")
p.add_mesh(pv.Sphere(radius=0.4), color="red")
img = p.screenshot(return_img=True)
name = type(p.ren_win).__name__
p.close()
red = (img[..., 0].astype(int) - img[..., 1]).max() > 100
print("PHYSLAB_PYVISTA_OK" if img.shape[:2] == (32, 32) and red else "PHYSLAB_PYVISTA_BLANK",
      name)
"""


@functools.lru_cache(maxsize=1)
def _probe_pyvista():
    """(ok, detail): can PyVista render offscreen here? Tried once per process, in a
    subprocess (a missing GL / EGL stack can crash the interpreter instead of raising)."""
    try:
        import importlib.util

        if importlib.util.find_spec("pyvista") is None:
            return False, "pyvista is not installed"
        out = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True,
                             timeout=120, check=False)
    except (OSError, subprocess.TimeoutExpired) as e:
        return False, f"the offscreen probe failed: {e}"
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("PHYSLAB_PYVISTA")]
    if out.returncode == 0 and lines and lines[-1].startswith("PHYSLAB_PYVISTA_OK"):
        return True, lines[-1].split()[-1]
    code = out.returncode
    try:
        why = f"killed by {signal.Signals(-code).name}" if code < 0 else f"exit code {code}"
    except ValueError:
        why = f"exit code {code}"
    err = re.sub(r"\x1b\[[0-9;]*m", "", out.stderr).strip().splitlines() or ["no output"]
    detail = lines[-1] if lines else err[-1].split("| ")[-1].strip()
    return False, f"the offscreen test render failed, {why}: {detail}"


def pyvista_offscreen_available():
    """True if PyVista can render offscreen in this process's environment (probed once)."""
    return _probe_pyvista()[0]


@functools.cache
def _warn_fallback(detail):
    warnings.warn(f"PyVista cannot render offscreen here ({detail}); physlab.viz.view3d falls "
                  f"back to matplotlib. For the PyVista view install Mesa's EGL or OSMesa "
                  f"(apt-get install libegl1 libgl1 / libosmesa6) or run under a display",
                  RuntimeWarning, stacklevel=3)


def resolve_backend(backend="auto"):
    """``"pyvista"`` or ``"matplotlib"``: ``"auto"`` picks PyVista when it can render
    offscreen, else matplotlib with a warning (once per process); ``"pyvista"`` raises
    RuntimeError when it cannot render."""
    if backend not in ("auto", "pyvista", "matplotlib"):
        raise ValueError(f"backend must be 'auto', 'pyvista' or 'matplotlib', got {backend!r}")
    if backend == "matplotlib":
        return backend
    ok, detail = _probe_pyvista()
    if ok:
        return "pyvista"
    if backend == "pyvista":
        raise RuntimeError(f"PyVista cannot render offscreen here ({detail}); use "
                           f"backend='matplotlib' or 'auto'")
    _warn_fallback(detail)
    return "matplotlib"


# ----------------------------------------------------------------------------- camera


def _view_direction(camera):
    if isinstance(camera, str):
        if camera not in CAMERAS:
            raise ValueError(f"camera must be one of {', '.join(CAMERAS)}, a view direction "
                             f"(3,) or (position, focal_point, view_up), got {camera!r}")
        v = np.array(CAMERAS[camera], float)
    else:
        v = np.asarray(camera, dtype=float)
        if v.shape != (3,) or not np.linalg.norm(v) > 0:
            raise ValueError(f"camera must be a name, a non-zero view direction (3,) or "
                             f"(position, focal_point, view_up), got {camera!r}")
    return v / np.linalg.norm(v)


def _camera_position(camera, points, size, pad=0.0, view_angle=_VIEW_ANGLE, margin=1.06):
    """(position, focal_point, view_up) framing ``points`` (n, 3) from direction ``camera``.

    The focal point centres the points on screen (in the camera's right / up axes) and the
    distance is the smallest at which every point, grown by ``pad`` metres, lies inside the
    perspective frustum (vertical angle ``view_angle``, aspect ``width / height``):
    ``dist >= (|p·right| + pad) / tan(fov_h / 2) + p·dir`` and likewise with ``up``."""
    if not isinstance(camera, str) and np.shape(camera) == (3, 3):
        pos, foc, up = (tuple(map(float, v)) for v in np.asarray(camera, float))
        return [pos, foc, up]
    d = _view_direction(camera)
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    up0 = np.array([0, 0, -1.0]) if abs(d[1]) > 0.999 else np.array([0, 1.0, 0])
    right = np.cross(up0, d)
    right /= np.linalg.norm(right)
    up = np.cross(d, right)
    f = (p.min(0) + p.max(0)) / 2
    u, v = (p - f) @ right, (p - f) @ up
    f = f + right * (u.min() + u.max()) / 2 + up * (v.min() + v.max()) / 2
    q = p - f
    tv = np.tan(np.radians(view_angle) / 2)
    th = tv * size[0] / size[1]
    dist = max(np.max((np.abs(q @ right) + pad) / th + q @ d + pad),
               np.max((np.abs(q @ up) + pad) / tv + q @ d + pad))
    dist = margin * max(dist, 0.5)
    return [tuple(f + dist * d), tuple(f), tuple(up)]


# ----------------------------------------------------------------------------- pyvista scene


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


def _prepare(joints, keypose, keypose_frame, trajectories, size, radius):
    x = _check_joints(joints)
    keypose, keypose_frame = _check_keypose(x, keypose, keypose_frame)
    trajs = _check_trajectories(trajectories)
    return x, keypose, keypose_frame, trajs, _check_size(size), _radii(radius)


def _frame_indices(frames, T):
    if frames is None:
        return np.arange(T), False
    if np.ndim(frames) == 0:
        idx = np.array([frames])
        single = True
    else:
        idx, single = np.asarray(frames).reshape(-1), False
    if idx.size == 0 or not np.all(np.mod(idx, 1) == 0) or np.any((idx < -T) | (idx >= T)):
        raise ValueError(f"frames must be None, a frame index or indices in 0..{T - 1}, got "
                         f"{frames!r}")
    return idx.astype(int) % T, single


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
    radius : None, float or (22,) bone radii, see :func:`capsule_segments`.
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


def _strobe_indices(T, every, keypose_frame):
    if not float(every).is_integer() or every < 1:
        raise ValueError(f"every must be an integer >= 1 (frames between ghosts), got {every}")
    idx = list(range(0, T, int(every)))
    if idx[-1] != T - 1:
        idx.append(T - 1)
    if keypose_frame is not None and keypose_frame not in idx:
        idx = sorted(idx + [keypose_frame])
    return np.array(idx)


def _strobe_colors(n):
    w = np.linspace(0, 1, n)[:, None] if n > 1 else np.ones((1, 1))
    return (1 - w) * np.array(COLORS["strobe_first"]) + w * np.array(COLORS["strobe_last"])


def motion_plotter(joints, keypose=None, keypose_frame=None, trajectories=None, every=5,
                   frames=None, size=(640, 400), camera="iso", off_screen=True, ground="auto",
                   radius=None, offset=None):
    """A :class:`pyvista.Plotter` holding a stroboscopic scene of the clip (for
    :func:`strobe` and the notebook viewer of :func:`show_motion`); the caller closes it.

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


def strobe(joints, every=5, keypose=None, keypose_frame=None, trajectories=None, frames=None,
           size=(640, 400), camera="iso", backend="auto", ground="auto", radius=None,
           offset=None):
    """One image of several frames of a clip ghosted together (a "stroboscopic" view).

    See :func:`motion_plotter` for the parameters. ``backend``: ``"auto"``, ``"pyvista"``
    or ``"matplotlib"`` (:func:`resolve_backend`).

    Returns
    -------
    (H, W, 3) uint8 array, ``H, W = size[1], size[0]``.
    """
    if resolve_backend(backend) == "matplotlib":
        x = _check_joints(joints)
        kf = _check_keypose(x, keypose, keypose_frame)[1]
        idx = (_strobe_indices(len(x), every, kf) if frames is None
               else _frame_indices(frames, len(x))[0])
        fig = plot_motion_matplotlib(x, frames=idx, keypose=keypose, keypose_frame=keypose_frame,
                                     trajectories=trajectories, size=size, camera=camera,
                                     ground=ground, radius=radius, offset=offset)
        return _figure_rgb(fig)
    p = motion_plotter(joints, keypose=keypose, keypose_frame=keypose_frame,
                       trajectories=trajectories, every=every, frames=frames, size=size,
                       camera=camera, off_screen=True, ground=ground, radius=radius,
                       offset=offset)
    try:
        p.render()
        return np.array(p.screenshot(return_img=True)[..., :3], dtype=np.uint8)
    finally:
        p.close()


# ----------------------------------------------------------------------------- matplotlib


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
    lines whose width follows :data:`BONE_RADII`; the keypose is red, trajectories green,
    the ground a grey square.

    Parameters
    ----------
    joints : (T, 22, 3) or (22, 3) float array, metres.
    frames : None (a strobe of every ``every``-th frame; default ``every = ceil(T / 8)``),
        an int (one pose) or a sequence of frame indices (ghosted light -> dark).
    keypose, keypose_frame, trajectories, camera, ground, radius, offset : as in
        :func:`motion_plotter` (``camera`` as a direction or name sets elevation / azimuth).
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


def _render_matplotlib(x, idx, keypose, keypose_frame, trajs, size, camera, ground, r):
    fig, _, set_pose = _mpl_scene(x, idx[:1], keypose, keypose_frame, trajs, size, camera,
                                  ground, r, frame_all=True)
    out = []
    for t in idx:
        set_pose(x[t], keyed=(t == keypose_frame))
        out.append(_figure_rgb(fig))
    return out


def render_motion(joints, keypose=None, keypose_frame=None, trajectories=None, frames=None,
                  size=(400, 400), camera="iso", backend="auto", ground="auto", radius=None,
                  progress=False):
    """RGB frames of a clip with PyVista, or matplotlib when PyVista cannot render.

    Same parameters and return value as :func:`render_motion_pyvista`, plus ``backend``
    (``"auto"``, ``"pyvista"``, ``"matplotlib"``; see :func:`resolve_backend`).
    """
    if resolve_backend(backend) == "pyvista":
        return render_motion_pyvista(joints, keypose=keypose, keypose_frame=keypose_frame,
                                     trajectories=trajectories, frames=frames, size=size,
                                     camera=camera, ground=ground, radius=radius,
                                     progress=progress)
    x, keypose, keypose_frame, trajs, size, r = _prepare(joints, keypose, keypose_frame,
                                                         trajectories, size, radius)
    idx, single = _frame_indices(frames, len(x))
    out = _render_matplotlib(x, idx, keypose, keypose_frame, trajs, size, camera, ground, r)
    return out[0] if single else out


# ----------------------------------------------------------------------------- notebooks, files


def _jupyter_backend():
    """PyVista's notebook backend: ``"html"`` (a self-contained vtk.js scene you can orbit,
    needs trame-vtk) when available, else ``"static"`` (a screenshot)."""
    import importlib.util

    return "html" if importlib.util.find_spec("trame_vtk") is not None else "static"


def _in_kernel():
    """True inside a Jupyter (IPython) kernel."""
    try:
        from IPython import get_ipython
    except ImportError:
        return False
    ip = get_ipython()
    return ip is not None and "IPKernelApp" in getattr(ip, "config", {})


def show_motion(joints, keypose=None, keypose_frame=None, trajectories=None, backend="auto",
                interactive=True, every=5, fps=20, size=(480, 400), camera="iso",
                jupyter_backend=None, ground="auto", radius=None):
    """Show a clip in JupyterLab.

    * PyVista, ``interactive=True`` and running in a Jupyter kernel: a 3-D strobe scene
      (:func:`motion_plotter`) you can orbit, through PyVista's notebook backend
      ``jupyter_backend`` (default ``"html"``, a self-contained vtk.js scene, when trame-vtk
      is installed, else ``"static"``; ``"trame"`` needs a running trame server).
    * otherwise: an inline looping video of every frame (:func:`render_motion` ->
      :func:`physlab.render.frames_to_html`), with PyVista or the matplotlib fallback.

    Returns what Jupyter displays (a PyVista viewer or :class:`IPython.display.HTML`).
    """
    name = resolve_backend(backend)
    if name == "pyvista" and interactive and _in_kernel():
        p = motion_plotter(joints, keypose=keypose, keypose_frame=keypose_frame,
                           trajectories=trajectories, every=every, size=size, camera=camera,
                           off_screen=True, ground=ground, radius=radius)
        return p.show(jupyter_backend=jupyter_backend or _jupyter_backend(), return_viewer=True)
    from physlab.render import frames_to_html

    frames = render_motion(joints, keypose=keypose, keypose_frame=keypose_frame,
                           trajectories=trajectories, size=size, camera=camera, backend=name,
                           ground=ground, radius=radius)
    return frames_to_html(frames, fps=fps)


def motion_to_gif(joints, path, fps=20, backend="auto", **kwargs):
    """Render a clip (:func:`render_motion`, keyword arguments passed on) and write an
    animated GIF atomically (:func:`physlab.render.frames_to_gif`). Returns the Path."""
    from physlab.render import frames_to_gif

    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    frames = render_motion(joints, backend=backend, **kwargs)
    return frames_to_gif(np.asarray(frames).reshape((-1,) + np.shape(frames)[-3:]), path, fps=fps)


def motion_to_mp4(joints, path, fps=20, backend="auto", crf=23, **kwargs):
    """Render a clip (:func:`render_motion`) and write an H.264 MP4 atomically
    (:func:`physlab.render.frames_to_mp4`). Returns the Path."""
    from physlab.render import frames_to_mp4

    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    frames = render_motion(joints, backend=backend, **kwargs)
    return frames_to_mp4(np.asarray(frames).reshape((-1,) + np.shape(frames)[-3:]), path, fps=fps,
                         crf=crf)
