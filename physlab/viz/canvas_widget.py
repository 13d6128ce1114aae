"""Plumbing shared by physlab's ipycanvas widgets (:mod:`~physlab.viz.sketch_canvas`,
:mod:`~physlab.viz.occlusion_annotator`).

A widget callback that raises inside the kernel only writes to JupyterLab's log console, which
a student never opens. :class:`CanvasWidget` routes every button, observer and mouse callback
through :meth:`~CanvasWidget._guard`, which shows the error's message in the widget's readout
line instead. No ipywidgets or ipycanvas import happens here: the widgets import them lazily in
their constructors, so the package stays importable without a display.
"""
from __future__ import annotations

import numpy as np

__all__ = ["CanvasWidget", "png_bytes"]


def png_bytes(rgb):
    """PNG file bytes of an (H, W, 3|4) uint8 image (for an ``ipywidgets.Image``)."""
    import imageio.v3 as iio

    return iio.imwrite("<bytes>", np.asarray(rgb, dtype=np.uint8), extension=".png")


class CanvasWidget:
    """Mixin for a widget with a readout line: the subclass sets ``self.readout`` (an
    ``ipywidgets.HTML``) and ``self.widget`` (the box to show) in its constructor; the object
    then displays as its box in a notebook.

    Attributes
    ----------
    shown_errors : tuple of exception types that :meth:`_guard` shows in the readout (others
        propagate). Subclasses may widen it.
    """

    shown_errors = (ValueError, TypeError, OSError)

    @property
    def status(self):
        """The readout's current text (HTML)."""
        return self.readout.value

    def _say(self, text, error=False):
        color = "#b00020" if error else "#333"
        self.readout.value = f'<span style="color:{color}">{text}</span>'

    def _guard(self, f, *args):
        """Run a callback; show an error in the readout instead of losing it in the log."""
        try:
            f(*args)
        except self.shown_errors as e:
            self._say(f"{type(e).__name__}: {e}", error=True)

    def _on_clicks(self, pairs):
        """Connect each ``(button, callback)`` of ``pairs``; callbacks take no argument."""
        for b, f in pairs:
            b.on_click(lambda _b, f=f: self._guard(f))

    def _route_mouse(self, canvas, down, move, up):
        """Send the canvas's mouse down / move / up events ``(x, y)`` (canvas pixels) to the
        three handlers, through the guard."""
        canvas.on_mouse_down(lambda x, y: self._guard(down, x, y))
        canvas.on_mouse_move(lambda x, y: self._guard(move, x, y))
        canvas.on_mouse_up(lambda x, y: self._guard(up, x, y))

    def _repr_mimebundle_(self, **kwargs):
        return self.widget._repr_mimebundle_(**kwargs)
