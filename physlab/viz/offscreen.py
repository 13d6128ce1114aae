"""PyVista offscreen: importing PyVista for headless rendering and probing whether it works.

On Linux without ``$DISPLAY`` VTK >= 9.4 renders through EGL (Mesa's llvmpipe when there is
no GPU); :func:`_import_pyvista` sets ``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow`` in that
case (only if unset, and only when called — importing this module changes no environment) so
VTK does not try X first. Xvfb is not needed (``pyvista.start_xvfb`` is gone from PyVista
0.49); OSMesa works too when ``libOSMesa`` is installed
(``VTK_DEFAULT_OPENGL_WINDOW=vtkOSOpenGLRenderWindow``).

:func:`_probe_pyvista` tries a tiny offscreen render once per process, in a subprocess, since
a broken OpenGL stack can abort the interpreter instead of raising;
:func:`pyvista_offscreen_available` is its yes / no. Choosing a backend from the answer is
:func:`physlab.viz.view3d.resolve_backend`. PyVista is imported inside the functions only.
"""
from __future__ import annotations

import functools
import os
import re
import signal
import subprocess
import sys

__all__ = ["pyvista_offscreen_available"]


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
