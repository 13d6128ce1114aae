"""ipywidgets controls for the lessons.

A lesson's interactive cell is ``interact(callback, dt=float_slider(...), ...)`` where
``callback`` is a library function ``params -> Figure`` (tests call it directly). Sliders
use ``continuous_update=False``: the figure is recomputed when the handle is released.
"""
from __future__ import annotations

__all__ = ["float_slider", "log_slider", "int_slider", "dropdown", "interact"]

_STYLE = {"description_width": "initial"}
# "initial" shows a description in full; ipywidgets' default 300 px row then leaves a long
# one (lesson 08's "speedup (ε = speedup/(N−1))") no room for the track. A wider row keeps a
# track of >= 150 px next to descriptions up to ~40 characters (checked in the browser tests).
_SLIDER_LAYOUT = {"width": "520px", "max_width": "100%"}


def float_slider(value, min, max, step, description="", readout_format=".3g"):
    import ipywidgets as w

    return w.FloatSlider(value=value, min=min, max=max, step=step, description=description,
                         continuous_update=False, readout_format=readout_format, style=_STYLE,
                         layout=dict(_SLIDER_LAYOUT))


def log_slider(value, min, max, description="", base=10, step=0.05, readout_format=".3g"):
    """Slider over ``base**e`` for ``e`` in ``[log(min), log(max)]`` (e.g. dt, stiffness)."""
    import math

    import ipywidgets as w

    lo, hi = math.log(min, base), math.log(max, base)
    return w.FloatLogSlider(value=value, base=base, min=lo, max=hi, step=step, description=description,
                            continuous_update=False, readout_format=readout_format, style=_STYLE,
                            layout=dict(_SLIDER_LAYOUT))


def int_slider(value, min, max, step=1, description=""):
    import ipywidgets as w

    return w.IntSlider(value=value, min=min, max=max, step=step, description=description,
                       continuous_update=False, style=_STYLE, layout=dict(_SLIDER_LAYOUT))


def dropdown(options, value=None, description=""):
    import ipywidgets as w

    options = list(options)
    return w.Dropdown(options=options, value=options[0] if value is None else value,
                      description=description, style=_STYLE)


def interact(callback, **controls):
    """An :func:`ipywidgets.interactive` box running ``callback(**values)`` on every change
    and displaying the Figure it returns. Plain values in ``controls`` are held fixed, and
    so are the callback's other keyword parameters (at their defaults).

    Returns the widget (display it, or let it be the cell's last expression)."""
    import inspect

    import ipywidgets as w

    fixed = {k: w.fixed(v) for k, v in controls.items() if not isinstance(v, w.Widget)}
    live = {k: v for k, v in controls.items() if isinstance(v, w.Widget)}
    for name, par in inspect.signature(callback).parameters.items():  # others keep defaults
        if name not in controls and par.default is not inspect.Parameter.empty:
            fixed[name] = w.fixed(par.default)
    # auto_display: show the returned Figure (plain `interactive` would only compute it)
    box = w.interactive(callback, {"auto_display": True}, **live, **fixed)
    box.layout = w.Layout(width="100%")
    return box
