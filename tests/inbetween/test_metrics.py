"""Tests of physlab.inbetween.metrics: PSNR, SSIM, Chamfer distance, LPIPS availability."""
import importlib.util

import numpy as np
import pytest
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

from physlab.inbetween.frame_interpolation import over_white
from physlab.inbetween.metrics import (CD_SCALE, chamfer, ink_mask, lpips_available, lpips_status,
                                       psnr, ssim)


def _random_rgba(rng, n=32):
    img = rng.random((n, n, 4)).astype(np.float32)
    img[..., 3] = rng.random((n, n)) > 0.3
    return img


def test_identical_images():
    rng = np.random.default_rng(0)
    a = _random_rgba(rng)
    assert psnr(a, a) == np.inf
    assert ssim(a, a) == pytest.approx(1.0)
    assert chamfer(a, a) == 0.0
    # colour under zero alpha does not matter: composited over white first
    b = a.copy()
    b[..., :3][a[..., 3] == 0] = rng.random(((a[..., 3] == 0).sum(), 3))
    assert psnr(a, b) == np.inf
    assert psnr(a, over_white(a)) == np.inf


def test_psnr_against_skimage_and_analytic():
    rng = np.random.default_rng(1)
    a, b = rng.random((24, 20, 3)), rng.random((24, 20, 3))
    assert psnr(a, b) == pytest.approx(peak_signal_noise_ratio(a, b, data_range=1.0), rel=1e-5)
    assert psnr(a, b) == psnr(b, a)
    assert psnr(np.zeros((8, 8, 3)), np.full((8, 8, 3), 0.1)) == pytest.approx(20.0)  # MSE 0.01
    a8 = (a * 255).round().astype(np.uint8)
    assert psnr(a8, b) == pytest.approx(psnr(a8 / 255.0, b), rel=1e-5)


def test_ssim_against_skimage():
    rng = np.random.default_rng(2)
    a = rng.random((32, 32, 3))
    b = np.clip(a + 0.1 * rng.standard_normal(a.shape), 0, 1)
    ref = structural_similarity(a, b, channel_axis=-1, data_range=1.0)
    assert ssim(a, b) == pytest.approx(ref, rel=1e-5)
    assert ssim(a, b) == pytest.approx(ssim(b, a), rel=1e-6)
    assert ssim(a, b) < 1
    with pytest.raises(ValueError, match="7×7"):
        ssim(a[:5, :5], b[:5, :5])


def _lines(H, W, cols):
    img = np.ones((H, W, 3), np.float32)
    for c in cols:
        img[:, c] = 0.0
    return img


@pytest.mark.parametrize("d", [1, 3, 10])
def test_chamfer_two_lines(d):
    H, W = 40, 64
    a, b = _lines(H, W, [20]), _lines(H, W, [20 + d])
    diag = np.hypot(H, W)
    expected = d / diag * (H / (H * W))                      # (d / diag) · ink fraction
    assert chamfer(a, b) == pytest.approx(expected, rel=1e-12)
    assert chamfer(b, a) == chamfer(a, b)                    # symmetric
    assert chamfer(a, b, scale=CD_SCALE) == pytest.approx(1e5 * expected, rel=1e-12)


def test_chamfer_no_ink_and_rgba():
    H, W = 30, 40
    blank = np.ones((H, W, 3))
    a = _lines(H, W, [5])
    # one side without ink: its distance transform is the diagonal everywhere
    assert chamfer(a, blank) == pytest.approx(H / (2 * H * W), rel=1e-12)
    assert chamfer(blank, blank) == 0.0
    # ink from an RGBA drawing: black strokes with alpha, transparent elsewhere
    rgba = np.zeros((H, W, 4), np.float32)
    rgba[:, 5, 3] = 1.0
    np.testing.assert_array_equal(ink_mask(rgba), ink_mask(a))
    assert chamfer(rgba, a) == 0.0
    # fixed reference number: a 1-px square outline against a shifted copy
    sq = np.ones((H, W, 3))
    sq[5:20, 5] = sq[5:20, 19] = sq[5, 5:20] = sq[19, 5:20] = 0
    shifted = np.roll(sq, (2, 1), axis=(0, 1))
    assert chamfer(sq, shifted, scale=CD_SCALE) == pytest.approx(134.41713589978812, rel=1e-9)


def test_metric_errors():
    with pytest.raises(ValueError, match="same size"):
        psnr(np.zeros((4, 4, 3)), np.zeros((4, 5, 3)))
    with pytest.raises(ValueError, match="threshold"):
        chamfer(np.zeros((4, 4, 3)), np.zeros((4, 4, 3)), threshold=0)


def test_lpips_status():
    ok, why = lpips_status()
    assert isinstance(ok, bool) and isinstance(why, str) and why
    assert lpips_available() is ok
    if importlib.util.find_spec("lpips") is None:
        assert not ok and "lpips" in why
