"""Images in one place: conversion to float RGB(A) in [0, 1], compositing over white, 8-bit
output, and reading image files with clear errors.

Conventions (DESIGN.md): images are ``(H, W)``, ``(H, W, 1)``, ``(H, W, 3)`` or
``(H, W, 4)`` arrays; RGBA is *straight* (not premultiplied). Accepted dtypes and how they
are read:

* ``uint8`` — 0..255;
* ``uint16`` — 0..65535 (16-bit PNGs), converted **by value range**, never wrapped by
  ``astype(uint8)``;
* ``bool`` — False = 0, True = 1;
* float — must be finite and in [0, 1] (a tolerance of 1e-6 is clipped).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["as_float", "over_white", "to_uint8", "read_image"]

_SCALE = {np.dtype(np.uint8): 1 / 255, np.dtype(np.uint16): 1 / 65535}


def _check_shape(shape, name, min_size=1):
    """ValueError naming ``name`` unless ``shape`` is (H, W) or (H, W, 1|3|4), H, W >= min_size."""
    if len(shape) not in (2, 3) or (len(shape) == 3 and shape[2] not in (1, 3, 4)):
        raise ValueError(f"{name} must be an image of shape (H, W), (H, W, 3) or (H, W, 4), got "
                         f"{shape}")
    if min(shape[:2]) < max(1, min_size):
        raise ValueError(f"{name} is empty or too small: shape {shape}, need H, W >= "
                         f"{max(1, min_size)}")


def _unit(a, name, dtype, clip=False):
    """Values of ``a`` (any shape) as ``dtype`` floats in [0, 1], read by dtype (module doc).

    ``clip``: floats outside [0, 1] are clipped instead of rejected (NaN / inf never are)."""
    if a.dtype in _SCALE:
        return a.astype(dtype) * np.dtype(dtype).type(_SCALE[a.dtype])
    if a.dtype == bool:
        return a.astype(dtype)
    if np.issubdtype(a.dtype, np.floating):
        f = a.astype(dtype)
        if not np.isfinite(f).all():
            raise ValueError(f"{name} contains NaN or inf")
        if not clip and (f.min() < -1e-6 or f.max() > 1 + 1e-6):
            raise ValueError(f"{name} floats must lie in [0, 1], got range [{f.min():g}, "
                             f"{f.max():g}] (scale 0..255 data by 1/255, or pass uint8)")
        return np.clip(f, 0.0, 1.0)
    raise ValueError(f"{name} must be uint8, uint16, bool or float in [0, 1], got dtype "
                     f"{a.dtype}")


def as_float(image, name="image", channels=None, dtype=np.float32, min_size=1):
    """``image`` as a float array in [0, 1].

    Parameters
    ----------
    image : (H, W) or (H, W, 1|3|4) array, uint8, uint16, bool or float in [0, 1].
    name : str, names the argument in error messages.
    channels : None (keep: (H, W) stays 2-D, one channel stays one), 3 (grey -> RGB, RGBA
        kept as is: the caller composites) or 4 (grey / RGB become opaque RGBA).
    dtype : float dtype of the result.
    min_size : int, smallest accepted H and W.

    Returns
    -------
    float array, (H, W[, C]).

    Raises
    ------
    ValueError naming ``name`` for another shape, an empty or too small image, another
    dtype, NaN/inf, floats outside [0, 1].
    """
    a = np.asarray(image)
    _check_shape(a.shape, name, min_size)
    f = _unit(a, name, dtype)
    if channels is None:
        return f
    if channels not in (3, 4):
        raise ValueError(f"channels must be None, 3 or 4, got {channels!r}")
    if f.ndim == 2:
        f = f[:, :, None]
    if f.shape[2] == 1:
        f = np.repeat(f, 3, axis=2)
    if channels == 4 and f.shape[2] == 3:
        f = np.concatenate([f, np.ones(f.shape[:2] + (1,), f.dtype)], axis=2)
    return f


def over_white(img):
    """Composite straight RGBA over white: ``rgb·a + (1 − a)``.

    ``img`` : (..., H, W, 3|4) float in [0, 1] (RGB is returned unchanged) or an image
    :func:`as_float` accepts. Returns (..., H, W, 3) float32."""
    a = np.asarray(img)
    # one image: validated and converted; a stack (T, H, W, C): already float in [0, 1]
    a = as_float(a, channels=3) if a.ndim <= 3 else a.astype(np.float32, copy=False)
    if a.shape[-1] == 3:
        return a
    alpha = a[..., 3:4]
    return a[..., :3] * alpha + (1.0 - alpha)


def to_uint8(image, name="image", clip=False):
    """``image`` as uint8, rounding to nearest: ``floor(x·255 + 0.5)`` of its [0, 1] value.

    Parameters
    ----------
    image : (H, W) or (H, W, 1|3|4) image, or a stack (T, H, W, 1|3|4) of them, of a dtype
        :func:`as_float` accepts. uint8 is returned as is (no copy); uint16 becomes
        ``round(x / 257)``; bool 0 / 255; a float is scaled in its own precision (float32
        stays float32, as ``(x * 255 + 0.5).astype(np.uint8)`` does).
    name : str, names the argument in error messages.
    clip : bool, clip floats outside [0, 1] (a renderer's overshoot) instead of rejecting
        them; NaN / inf are always rejected.

    Returns
    -------
    uint8 array of the same shape.
    """
    a = np.asarray(image)
    if a.dtype == np.uint8:
        return a
    _check_shape(a.shape[1:] if a.ndim == 4 else a.shape, name)
    dtype = a.dtype if np.issubdtype(a.dtype, np.floating) else np.float64
    return (_unit(a, name, dtype, clip) * 255 + 0.5).astype(np.uint8)


def read_image(path, name="image"):
    """Read an image file as an array (uint8 or uint16 as stored, (H, W[, C])).

    FileNotFoundError naming the path if it does not exist; ValueError naming it if it is
    not a readable image (a truncated PNG, a text file ...)."""
    import imageio.v3 as iio

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{name} file {path} does not exist")
    try:
        img = np.asarray(iio.imread(path, plugin="pillow"))
    except Exception as e:  # noqa: BLE001 - imageio/pillow raise many kinds
        raise ValueError(f"{name} file {path} is not a readable image ({type(e).__name__}: "
                         f"{str(e).strip()[:200]})") from None
    as_float(img, f"{name} file {path}")                          # shape / dtype check
    return img
