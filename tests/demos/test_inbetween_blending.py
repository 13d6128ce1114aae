"""physlab.demos.inbetween_blending: lesson 08's widget callback and figures (tiny sizes)."""
import numpy as np
import pytest
from matplotlib.figure import Figure

from physlab.demos import inbetween_blending as demo

SMALL = dict(pair="arm_swing", size=96, n_frames=5)


@pytest.fixture(scope="module")
def prep():
    return demo.prepared_pair(**SMALL)


def _draws(fig, tmp_path):
    assert isinstance(fig, Figure)
    fig.savefig(tmp_path / "f.png", dpi=50)
    assert (tmp_path / "f.png").stat().st_size > 3_000


@pytest.mark.parametrize("kw", [
    dict(),
    dict(speedup=1),                                   # ε = 1/(n − 1): only the diagonal fits
    dict(speedup=4, lambda_Q=0.0, texture_model="linear"),
    dict(blend="diagonal"),
])
def test_blending_demo_returns_a_figure_showing_a_valid_path(kw, tmp_path, prep):
    fig = demo.blending_demo(**kw, **SMALL)
    _draws(fig, tmp_path)
    c = demo.choose_path(prep, **kw)
    # the green line of the path panel is the chosen path
    green = [ln for ln in fig.axes[0].lines if ln.get_label().startswith("chosen path")]
    assert len(green) == 1
    np.testing.assert_allclose(green[0].get_xdata(), c.path.alphas)
    a = c.path.alphas
    assert a[0] == 0.0 and a[-1] == 1.0
    assert np.all(np.diff(a) >= 0) and np.all(np.diff(a) <= c.eps + 1e-9)
    assert c.path.cost <= c.diagonal.cost + 1e-12
    assert c.frames.shape == prep.result.fwd.shape
    assert c.psnr_path.shape == (SMALL["n_frames"] - 2,) and np.all(c.psnr_path > 15)


def test_speedup_one_leaves_only_the_diagonal(prep):
    c = demo.choose_path(prep, speedup=1)
    np.testing.assert_allclose(c.path.alphas, prep.result.t)
    np.testing.assert_allclose(c.psnr_path, c.psnr_diagonal)


def test_diagonal_frames_match_the_diagonal_path(prep):
    c = demo.choose_path(prep, blend="diagonal")
    np.testing.assert_allclose(c.frames[1:-1], prep.diagonal_frames[1:-1], atol=1e-6)


def test_prepared_pair_is_cached_and_read_only(prep):
    assert demo.prepared_pair(**SMALL) is prep
    assert prep.truth.shape == (5, 96, 96, 4) and prep.truth.dtype == np.uint8
    with pytest.raises(ValueError):
        prep.result.fwd[0, 0, 0, 0] = 1.0


@pytest.mark.parametrize("kw, match", [
    (dict(speedup=0.5), "speedup"),
    (dict(lambda_Q=-1.0), "lambda_Q"),
    (dict(texture_model="bogus"), "texture_model"),
    (dict(blend="zigzag"), "blend"),
    (dict(pair="moonwalk"), "pair"),
    (dict(size=32), "size"),
    (dict(n_frames=2), "n_frames"),
    (dict(n_frames=5.5), "n_frames"),
])
def test_bad_parameters_raise(kw, match):
    args = {**SMALL, **kw}
    with pytest.raises(ValueError, match=match):
        demo.blending_demo(**args)


def test_static_figures(tmp_path, prep):
    res = prep.result
    _draws(demo.sequences_figure(res), tmp_path)
    _draws(demo.flow_row_figure(res, 2, alphas=(0.0, 0.5, 1.0)), tmp_path)
    _draws(demo.costs_figure(res), tmp_path)
    with pytest.raises(ValueError, match="row"):
        demo.flow_row_figure(res, 5)


def test_foreground_box_and_side_by_side():
    img = np.zeros((20, 30, 4), np.uint8)
    img[5:8, 10:12, 3] = 255                             # a 3 × 2 opaque patch
    rows, cols = demo.foreground_box(img, margin=2)
    assert (rows.start, rows.stop, cols.start, cols.stop) == (3, 10, 8, 14)
    assert demo.foreground_box(np.zeros((4, 4, 4))) == (slice(0, 4), slice(0, 4))
    out = demo.side_by_side(np.stack([img] * 3), np.ones((3, 20, 10, 3), np.float32), gap=4)
    assert out.shape == (3, 20, 44, 3) and out.dtype == np.uint8
    assert np.all(out[:, :, 30:34] == 255)               # the white gap
    with pytest.raises(ValueError):
        demo.side_by_side(np.zeros((3, 20, 30, 4)), np.zeros((2, 20, 30, 4)))


def test_pair_names_match_the_benchmark():
    from physlab.inbetween import inbetween_benchmark

    pairs = inbetween_benchmark(64)
    assert tuple(p.name for p in pairs) == demo.PAIR_NAMES
    assert all(p.kind == "far" for p in pairs[6:])        # the lesson's dropdown offers these
