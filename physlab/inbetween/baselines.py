"""Inbetweening baselines that use no skeleton (Brodt & Bessmeltsev 2024, Table 1 and Fig. 13).

* :func:`cross_dissolve` — fade from key 0 to key 1.
* :func:`flow_interpolation` — a video frame interpolator applied directly to the two
  keyframes: the row ``α = t`` of an "image matrix" with a single pair. With the default
  :class:`~physlab.inbetween.frame_interpolation.FlowInterpolator` this is physlab's stand-in for the
  RIFE row of Table 1; pass another interpolator to compare others.
"""
from __future__ import annotations

import numpy as np

from .frame_interpolation import CrossDissolve, FlowInterpolator

__all__ = ["cross_dissolve", "flow_interpolation"]


def _times(n_frames):
    n = int(n_frames)
    if n != n_frames or n < 2:
        raise ValueError(f"n_frames must be an integer ≥ 2 (the two keys included), "
                         f"got {n_frames}")
    return np.linspace(0.0, 1.0, n)


def cross_dissolve(key0, key1, n_frames):
    """Fade between the keys in premultiplied colour.

    Parameters
    ----------
    key0, key1 : (H, W, 3|4) images, uint8 or float in [0, 1], same shape.
    n_frames : int ≥ 2, frames including both keys.

    Returns
    -------
    (n_frames, H, W, C) float32; frame 0 = key0, frame −1 = key1.
    """
    return CrossDissolve()(key0, key1, _times(n_frames))


def flow_interpolation(key0, key1, n_frames, interpolator=None):
    """Frame interpolation straight between the keys, ``I(t) = F(key0, key1, t)``.

    Parameters
    ----------
    key0, key1 : (H, W, 3|4) images, uint8 or float in [0, 1], same shape.
    n_frames : int ≥ 2, frames including both keys.
    interpolator : FrameInterpolator, default ``FlowInterpolator()`` (the RIFE analogue).

    Returns
    -------
    (n_frames, H, W, C) float32; frame 0 = key0, frame −1 = key1.
    """
    interp = FlowInterpolator() if interpolator is None else interpolator
    return interp(key0, key1, _times(n_frames))
