"""Tests of physlab.inbetween.frame_interpolation (and the baselines built on it)."""
import numpy as np
import pytest
from scipy.ndimage import binary_erosion, gaussian_filter, map_coordinates

from physlab.inbetween.baselines import cross_dissolve, flow_interpolation
from physlab.inbetween.frame_interpolation import (CrossDissolve, FlowInterpolator, FrameInterpolator,
                                           as_image, flow_image, over_white)

N = 96
D = np.array([6.0, -4.0])          # translation (x, y) in px
C0 = np.array([42.0, 50.0])        # disk centre in key 0
R = 24.0


def _texture(seed=0, sigma=1.5):
    rng = np.random.default_rng(seed)
    tex = gaussian_filter(rng.random((128, 128)), sigma, mode="wrap")
    return (tex - tex.min()) / (tex.max() - tex.min())


def textured_disk(centre, tex, n=N, r=R):
    """(n, n, 4) straight RGBA: an antialiased disk whose texture moves with it."""
    yy, xx = np.mgrid[0:n, 0:n].astype(float)
    u, v = xx - centre[0], yy - centre[1]
    t = map_coordinates(tex, [v + 64, u + 64], order=1, mode="grid-wrap")
    img = np.zeros((n, n, 4), np.float32)
    img[..., 0], img[..., 1], img[..., 2] = t, 1 - t, 0.3 + 0.4 * t
    img[..., 3] = np.clip(r + 0.5 - np.hypot(u, v), 0, 1)
    return img


@pytest.fixture(scope="module")
def disks():
    tex = _texture()
    return (textured_disk(C0, tex), textured_disk(C0 + D, tex),
            textured_disk(C0 + D / 2, tex))


INTERPOLATORS = [FlowInterpolator(), FlowInterpolator(method="farneback"), CrossDissolve()]


def test_protocol():
    for f in INTERPOLATORS:
        assert isinstance(f, FrameInterpolator)


@pytest.mark.parametrize("interp", INTERPOLATORS, ids=repr)
def test_endpoints_exact_shapes_dtype(interp, disks):
    a, b, _ = disks
    out = interp(a, b, [0.0, 0.25, 0.5, 1.0])
    assert out.shape == (4, N, N, 4) and out.dtype == np.float32
    np.testing.assert_array_equal(out[0], a)
    np.testing.assert_array_equal(out[-1], b)
    assert out.min() >= 0 and out.max() <= 1
    # uint8 RGB in, float32 RGB out, still exact at the ends
    a8 = (over_white(a) * 255).astype(np.uint8)
    b8 = (over_white(b) * 255).astype(np.uint8)
    out = interp(a8, b8, np.array([1.0, 0.0, 0.5]))
    assert out.shape == (3, N, N, 3) and out.dtype == np.float32
    np.testing.assert_array_equal(out[0], as_image(b8))
    np.testing.assert_array_equal(out[1], as_image(a8))
    f = interp.flow(a, b)
    assert f.shape == (N, N, 2) and f.dtype == np.float32


@pytest.mark.parametrize("method", ["dis", "farneback"])
def test_translated_disk_flow(method, disks):
    a, b, _ = disks
    fi = FlowInterpolator(method=method)
    inside = binary_erosion(a[..., 3] > 0.99, iterations=2)
    f01, f10 = fi.flow_pair(a, b)
    err = np.linalg.norm(f01[inside] - D, axis=1)
    assert np.median(err) < 0.5
    inside1 = binary_erosion(b[..., 3] > 0.99, iterations=2)
    assert np.median(np.linalg.norm(f10[inside1] + D, axis=1)) < 0.5
    np.testing.assert_array_equal(fi.flow(a, b), f01)          # deterministic, same as pair


def test_middle_frame_beats_cross_dissolve(disks):
    a, b, half = disks
    ref = over_white(half)
    e_flow = np.abs(over_white(FlowInterpolator()(a, b, [0.5])[0]) - ref).mean()
    e_cd = np.abs(over_white(CrossDissolve()(a, b, [0.5])[0]) - ref).mean()
    assert e_flow < 0.1 * e_cd
    assert e_flow < 2e-3                                           # reference: ≈ 6e-5


def test_motion_is_monotone_in_alpha(disks):
    a, b, _ = disks
    al = np.linspace(0, 1, 9)
    frames = FlowInterpolator()(a, b, al)
    yy, xx = np.mgrid[0:N, 0:N]
    w = frames[..., 3]
    cx = (w * xx).sum((1, 2)) / w.sum((1, 2))
    cy = (w * yy).sum((1, 2)) / w.sum((1, 2))
    # the silhouette's centroid travels along the translation, linearly in α
    np.testing.assert_allclose(cx - cx[0], al * D[0], atol=0.15)
    np.testing.assert_allclose(cy - cy[0], al * D[1], atol=0.15)
    assert np.all(np.diff(cx) > 0) and np.all(np.diff(cy) < 0)
    # area is preserved (a translation), unlike a cross-dissolve's union of two disks
    np.testing.assert_allclose(w.sum((1, 2)), w[0].sum(), rtol=2e-3)


def test_identical_images_are_a_fixed_point(disks):
    a = disks[0]
    fi = FlowInterpolator()
    np.testing.assert_allclose(fi.flow(a, a), 0, atol=1e-3)
    out = fi(a, a, [0.3, 0.7])
    # colour under zero alpha is undefined (returned as 0): compare over white
    np.testing.assert_allclose(over_white(out), np.broadcast_to(over_white(a), out[..., :3].shape),
                               atol=1e-3)
    np.testing.assert_allclose(out[..., 3], np.broadcast_to(a[..., 3], out[..., 3].shape),
                               atol=1e-3)


def test_cross_dissolve_premultiplied_reference():
    a = np.array([[[1.0, 0.0, 0.0, 1.0]]], np.float32)   # opaque red
    b = np.array([[[0.0, 0.0, 1.0, 0.5]]], np.float32)   # half-transparent blue
    out = CrossDissolve()(a, b, [0.5])[0, 0, 0]
    # premultiplied: (0.5, 0, 0.25, 0.75) -> straight (2/3, 0, 1/3, 3/4)
    np.testing.assert_allclose(out, [2 / 3, 0, 1 / 3, 0.75], rtol=1e-6)
    np.testing.assert_array_equal(CrossDissolve().flow(a, b), np.zeros((1, 1, 2)))


def test_occlusion_masks_forward_backward_check():
    fi = FlowInterpolator()
    f01 = np.broadcast_to(np.float32([3.0, 0.0]), (16, 16, 2)).copy()
    o0, o1 = fi.occlusion_masks(f01, -f01)
    assert o0.max() == 0 and o1.max() == 0                  # consistent everywhere
    o0, o1 = fi.occlusion_masks(f01, np.zeros_like(f01))    # |3|² > 0.01·9 + 0.5
    assert o0.min() == 1 and o1.min() == 1


def test_flow_image():
    img = np.zeros((2, 2, 4), np.float32)
    img[0, 0] = [1, 1, 1, 1]                                # opaque white
    img[0, 1] = [0, 0, 0, 1]                                # opaque black
    g = flow_image(img, silhouette_weight=0.25)
    assert g[1, 0] == 255 and g[0, 1] == 0                  # background stays white
    assert g[0, 0] == round(0.75 * 255)                     # white character still visible


def test_as_image_and_errors(disks):
    a, b, _ = disks
    assert as_image(np.zeros((4, 5))).shape == (4, 5, 3)
    fi = FlowInterpolator()
    with pytest.raises(ValueError, match="same shape"):
        fi(a, b[:-1], [0.5])
    with pytest.raises(ValueError, match="same shape"):
        fi(a, b[..., :3], [0.5])
    bad = a.copy()
    bad[3, 3, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        fi(bad, b, [0.5])
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        fi(a * 255, b, [0.5])
    with pytest.raises(ValueError, match=r"alphas must lie in \[0, 1\]"):
        fi(a, b, [0.5, 1.2])
    with pytest.raises(ValueError, match="NaN"):
        CrossDissolve()(a, b, [np.nan])
    with pytest.raises(ValueError, match="shape"):
        fi(a[..., 0:2], b[..., 0:2], [0.5])
    with pytest.raises(ValueError, match="method"):
        FlowInterpolator(method="rife")
    with pytest.raises(ValueError, match="preset"):
        FlowInterpolator(preset="fine")
    with pytest.raises(ValueError, match="f01 must have shape"):
        fi.interpolate_with_flows(a, b, [0.5], np.zeros((3, 3, 2)), np.zeros((N, N, 2)))


def test_baselines(disks):
    a, b, half = disks
    for frames in (cross_dissolve(a, b, 5), flow_interpolation(a, b, 5),
                   flow_interpolation(a, b, 5, interpolator=CrossDissolve())):
        assert frames.shape == (5, N, N, 4) and frames.dtype == np.float32
        np.testing.assert_array_equal(frames[0], a)
        np.testing.assert_array_equal(frames[-1], b)
    np.testing.assert_array_equal(flow_interpolation(a, b, 3, CrossDissolve()),
                                  cross_dissolve(a, b, 3))
    mid = flow_interpolation(a, b, 3)[1]
    assert np.abs(over_white(mid) - over_white(half)).mean() < 2e-3
    with pytest.raises(ValueError, match="n_frames"):
        cross_dissolve(a, b, 1)
