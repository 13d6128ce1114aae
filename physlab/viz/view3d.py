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
      (Mesa's llvmpipe when there is no GPU); PyVista is imported with
      ``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow`` in that case (only if unset) so VTK does
      not try X first (:mod:`physlab.viz.offscreen`). Xvfb is not needed; OSMesa works too
      when ``libOSMesa`` is installed (``VTK_DEFAULT_OPENGL_WINDOW=vtkOSOpenGLRenderWindow``).
    * matplotlib 3-D axes, the fallback: ``backend="auto"`` probes once per process (in a
      subprocess, since a broken OpenGL stack can abort the interpreter) whether PyVista can
      render offscreen, and otherwise uses matplotlib with a single warning.

PyVista (and VTK) are imported inside the functions, so importing this module is cheap.

This module is the public face of the 3-D views: it chooses the backend
(:func:`resolve_backend`), dispatches to it, and shows or saves the result. The parts live in
one module per concept, and every public name is re-exported here:

* :mod:`physlab.viz.capsules` — the capsule-bone human: :data:`BONE_RADII`,
  :func:`capsule_segments`, :func:`capsule_arrays` (pure numpy);
* :mod:`physlab.viz.motion_scene` — what every view shows: :data:`COLORS`, argument checks,
  ground placement, strobe ghosts;
* :mod:`physlab.viz.camera` — :data:`CAMERAS` and framing the scene;
* :mod:`physlab.viz.offscreen` — importing PyVista headless and the offscreen probe
  (:func:`pyvista_offscreen_available`);
* :mod:`physlab.viz.scene_pyvista` — :func:`skeleton_meshes`, :func:`render_motion_pyvista`,
  :func:`motion_plotter`;
* :mod:`physlab.viz.scene_mpl` — :func:`plot_motion_matplotlib`, the fallback.

Main functions: :func:`skeleton_meshes` (one pose -> meshes), :func:`render_motion_pyvista`
and :func:`render_motion` (clip -> RGB frames), :func:`strobe` (several frames ghosted in one
image, the usual way papers show a motion), :func:`plot_motion_matplotlib` (-> Figure),
:func:`show_motion` (notebooks), :func:`motion_to_gif` / :func:`motion_to_mp4`.
"""
from __future__ import annotations

import functools
import warnings

import numpy as np

from physlab.viz.camera import CAMERAS
from physlab.viz.capsules import BONE_RADII, capsule_arrays, capsule_segments
from physlab.viz.motion_scene import COLORS
from physlab.viz.offscreen import _probe_pyvista, pyvista_offscreen_available
from physlab.viz.scene_mpl import (
    _render_motion_matplotlib,
    _strobe_matplotlib,
    _to_mpl,  # noqa: F401  (re-exported: tests check the axes map)
    plot_motion_matplotlib,
)
from physlab.viz.scene_pyvista import (
    _strobe_pyvista,
    motion_plotter,
    render_motion_pyvista,
    skeleton_meshes,
)

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


# ----------------------------------------------------------------------------- backend choice
# The choice lives in the façade and calls the probe through this module's namespace, so
# ``monkeypatch.setattr(view3d, "_probe_pyvista", ...)`` steers every function below.


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


# ----------------------------------------------------------------------------- dispatch


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
    draw = _strobe_matplotlib if resolve_backend(backend) == "matplotlib" else _strobe_pyvista
    return draw(joints, every, keypose, keypose_frame, trajectories, frames, size, camera,
                ground, radius, offset)


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
    return _render_motion_matplotlib(joints, keypose, keypose_frame, trajectories, frames, size,
                                     camera, ground, radius)


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
