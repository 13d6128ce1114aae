"""Argument checks shared by physlab's constructors: each raises ValueError / TypeError naming
the argument, what it got and what it needs."""
from __future__ import annotations

import numbers

import numpy as np


def number(value, name, lo=None, hi=None, lo_open=False, hi_open=False, integer=False):
    """``value`` as a finite float (or int with ``integer``) in the given bounds."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a {'whole ' if integer else ''}number, got "
                        f"{value!r} ({type(value).__name__})")
    v = float(value)
    if not np.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    if integer and v != int(v):
        raise ValueError(f"{name} must be a whole number, got {value!r}")
    if lo is not None and (v <= lo if lo_open else v < lo):
        raise ValueError(f"{name} must be {'>' if lo_open else '>='} {lo:g}, got {value!r}")
    if hi is not None and (v >= hi if hi_open else v > hi):
        raise ValueError(f"{name} must be {'<' if hi_open else '<='} {hi:g}, got {value!r}")
    return int(v) if integer else v


def vector(value, name, n=2):
    """``value`` as a finite float array of shape (n,)."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be {n} numbers, got {value!r}") from None
    if a.shape != (n,):
        raise ValueError(f"{name} must have {n} components, got {value!r}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return a
