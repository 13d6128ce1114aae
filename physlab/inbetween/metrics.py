"""Image metrics of Brodt & Bessmeltsev 2024, Table 1: PSNR, SSIM, LPIPS, Chamfer distance.

All metrics compare two images of the same shape, ``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)``,
uint8 or float in ``[0, 1]``. Drawings with an alpha channel are first **composited over
white** (straight alpha, ``rgb·a + 1 − a``), as the frames are shown on paper: two RGBA
images that differ only under zero alpha are identical here.

* :func:`psnr` — ``10 log10(1 / MSE)`` over all pixels and RGB channels, data range 1;
  identical images give ``inf`` (as ``skimage.metrics.peak_signal_noise_ratio``).
* :func:`ssim` — ``skimage.metrics.structural_similarity`` (Wang et al. 2004; 7×7 uniform
  window, ``channel_axis=-1``, ``data_range=1``), mean over the RGB channels.
* :func:`chamfer` — Chamfer distance between dark ("ink") pixels, the convention of
  Chen & Zwicker 2022 (EISAI) whose numbers the paper reports ×10⁵ (:data:`CD_SCALE`)::

      CD = [Σ_p ink_a(p)·DT_b(p) + Σ_p ink_b(p)·DT_a(p)] / (2·H·W·diag)

  ``DT_x(p)`` = Euclidean distance from p to the nearest ink pixel of x (``diag`` if x has
  none), ``diag = √(H² + W²)``. It is therefore a mean over *all* pixels (not over ink
  pixels): for two single-pixel lines ``d`` px apart, ``CD = (d / diag) · ink fraction``.
  EISAI extracts ink with a difference-of-Gaussians sketch filter; physlab thresholds the
  luminance over white (``ink = L < threshold``), the paper's "dark pixels".
* LPIPS (Zhang et al. 2018) needs pretrained AlexNet/VGG backbone weights that cannot be
  downloaded here; :func:`lpips_available` says whether it could run and
  :func:`lpips_status` why not.
"""
from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import numpy as np
from scipy.ndimage import distance_transform_edt
from skimage.metrics import structural_similarity

from .frame_interpolation import _LUMA, as_image, over_white

__all__ = ["psnr", "ssim", "chamfer", "ink_mask", "CD_SCALE", "lpips_available",
           "lpips_status"]

#: Table 1 of Brodt & Bessmeltsev 2024 reports CD × 10⁵ (and LPIPS × 10²).
CD_SCALE = 1e5


def _pair(a, b):
    """Validate, composite over white: two (H, W, 3) float64 arrays."""
    A, B = as_image(a, "a"), as_image(b, "b")
    if A.shape[:2] != B.shape[:2]:
        raise ValueError(f"images must have the same size, got {A.shape[:2]} and {B.shape[:2]}")
    return over_white(A).astype(np.float64), over_white(B).astype(np.float64)


def psnr(a, b):
    """Peak signal-to-noise ratio in dB, data range 1, RGBA composited over white.

    Parameters
    ----------
    a, b : (H, W), (H, W, 3) or (H, W, 4) images, uint8 or float in [0, 1].

    Returns
    -------
    float, ``10·log10(1 / mean((a − b)²))``; ``inf`` for identical images.
    """
    A, B = _pair(a, b)
    mse = np.mean((A - B) ** 2)
    return float("inf") if mse == 0 else float(10.0 * np.log10(1.0 / mse))


def ssim(a, b, **kwargs):
    """Structural similarity (Wang et al. 2004) via ``skimage.metrics.structural_similarity``.

    Parameters
    ----------
    a, b : (H, W), (H, W, 3) or (H, W, 4) images, uint8 or float in [0, 1]; both ≥ 7×7.
    **kwargs : passed to ``structural_similarity`` (e.g. ``gaussian_weights=True``).

    Returns
    -------
    float in [−1, 1], 1 for identical images.
    """
    A, B = _pair(a, b)
    if min(A.shape[:2]) < 7 and "win_size" not in kwargs:
        raise ValueError(f"ssim needs images of at least 7×7 pixels, got {A.shape[:2]} "
                         f"(or pass a smaller odd win_size)")
    return float(structural_similarity(A, B, channel_axis=-1, data_range=1.0, **kwargs))


def ink_mask(img, threshold=0.5):
    """Dark pixels of a drawing: luminance over white below ``threshold``.

    Parameters
    ----------
    img : (H, W), (H, W, 3) or (H, W, 4) image, uint8 or float in [0, 1].
    threshold : float in (0, 1], Rec. 709 luminance.

    Returns
    -------
    (H, W) bool.
    """
    if not 0.0 < threshold <= 1.0:
        raise ValueError(f"threshold must be in (0, 1], got {threshold}")
    return (over_white(as_image(img)) @ _LUMA) < threshold


def _distance_to_ink(ink, diag):
    """(H, W) bool -> (H, W) float64 Euclidean distance to the nearest True pixel."""
    if not ink.any():
        return np.full(ink.shape, diag)          # no ink: the diagonal (Chen & Zwicker 2022)
    return distance_transform_edt(~ink)


def chamfer(a, b, threshold=0.5, scale=1.0):
    """Chamfer distance between the dark pixels of two drawings (Chen & Zwicker 2022).

    ``CD = [Σ ink_a·DT_b + Σ ink_b·DT_a] / (2·H·W·diag)``; see the module docstring.

    Parameters
    ----------
    a, b : (H, W), (H, W, 3) or (H, W, 4) images, uint8 or float in [0, 1], same size.
    threshold : float, ink = luminance over white < threshold.
    scale : float, multiply the result (``CD_SCALE`` = 1e5 for Table 1's units).

    Returns
    -------
    float ≥ 0; 0 when the ink masks coincide (also when both have no ink).
    """
    A, B = _pair(a, b)
    if not 0.0 < threshold <= 1.0:
        raise ValueError(f"threshold must be in (0, 1], got {threshold}")
    ia, ib = (A @ _LUMA) < threshold, (B @ _LUMA) < threshold
    H, W = ia.shape
    diag = float(np.hypot(H, W))
    if not ia.any() and not ib.any():
        return 0.0
    total = (_distance_to_ink(ib, diag)[ia].sum() + _distance_to_ink(ia, diag)[ib].sum())
    return float(scale * total / (2.0 * H * W * diag))


# --------------------------------------------------------------------------- LPIPS
def lpips_status():
    """Whether LPIPS could be computed here, and why not.

    LPIPS needs the ``lpips`` package (its small linear heads ship inside it) **and** the
    pretrained torchvision AlexNet/VGG backbone, which ``lpips`` downloads on first use.
    Neither download is possible offline; this checks for the package, torchvision and a
    cached AlexNet checkpoint in the torch hub cache.

    Returns
    -------
    (bool, str) — available, and a reason / description.
    """
    if importlib.util.find_spec("lpips") is None:
        return False, ("the 'lpips' package is not installed, and its AlexNet/VGG backbone "
                       "weights (torchvision) cannot be downloaded offline")
    if importlib.util.find_spec("torchvision") is None:
        return False, "lpips is installed but torchvision (its backbone) is not"
    hub = Path(os.environ.get("TORCH_HOME", Path.home() / ".cache" / "torch")) / "hub"
    ckpts = list((hub / "checkpoints").glob("alexnet-*.pth")) if hub.exists() else []
    if not ckpts:
        return False, (f"no pretrained AlexNet checkpoint in {hub / 'checkpoints'}; LPIPS "
                       f"would try to download it")
    return True, f"lpips with AlexNet weights {ckpts[0].name}"


def lpips_available():
    """True if :func:`lpips_status` finds everything LPIPS needs (False here, offline)."""
    return lpips_status()[0]
