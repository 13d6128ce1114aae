"""Plotting, animation and widget helpers shared by the lessons.

Submodules: :mod:`~physlab.viz.plots` (static matplotlib figures),
:mod:`~physlab.viz.anim` (frames -> inline HTML5 video / GIF),
:mod:`~physlab.viz.widgets` (ipywidgets controls wrapping ``params -> Figure`` callbacks),
:mod:`~physlab.viz.view3d` (3D skeleton motions: pyvista capsule humans offscreen or in
JupyterLab, a matplotlib fallback; imported on demand, not here).
Figures are built as :class:`matplotlib.figure.Figure` objects without pyplot state, so a
callback can be called from a test, saved with ``fig.savefig``, or shown by a widget.
"""
from . import anim, plots, widgets  # noqa: F401
