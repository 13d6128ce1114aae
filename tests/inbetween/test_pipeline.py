"""The inbetweening pipeline end to end (Brodt & Bessmeltsev 2024, Secs. 4–5, no occlusions)."""
import numpy as np
import pytest
from _drawings import bar_drawing, bend

from physlab.inbetween import inbetween_benchmark
from physlab.inbetween import metrics
from physlab.inbetween.baselines import cross_dissolve
from physlab.inbetween.pipeline import inbetween
from physlab.inbetween.skeleton import Skeleton
from physlab.inbetween.template import as_rgba_float


@pytest.fixture(scope="module")
def far_pair():
    pair = next(p for p in inbetween_benchmark(size=128) if p.name == "arm_swing")
    k0, k1 = pair.keyframes()
    return pair, k0, k1


@pytest.fixture(scope="module")
def result(far_pair):
    pair, k0, k1 = far_pair
    return inbetween(k0, k1, pair.skeleton0, pair.skeleton1, 7, animation=pair.animation(7))


def test_frames_keys_and_intermediate_products(far_pair, result):
    pair, k0, k1 = far_pair
    r = result
    assert r.frames.shape == (7, 128, 128, 4) and r.frames.dtype == np.float32
    assert np.array_equal(r.frames[0], as_rgba_float(k0))
    assert np.array_equal(r.frames[-1], as_rgba_float(k1))
    assert r.fwd.shape == r.bwd.shape == (7, 128, 128, 4)
    assert r.x_fwd.shape[0] == r.x_bwd.shape[0] == 7
    assert r.flipped.sum() == 0                          # local injectivity in every frame
    assert r.handle_error.max() < 1.0                    # px, μ = 200
    # each deformed sequence starts at its own keyframe undeformed
    assert np.allclose(r.x_fwd[0], r.templates[0].X) and np.allclose(r.x_bwd[-1], r.templates[1].X)
    assert r.distortion_fwd[0] == 0 and r.distortion_bwd[-1] == 0
    assert r.distortion_fwd[-1] > 0 and r.distortion_bwd[0] > 0


def test_path_is_valid_and_no_worse_than_the_diagonal(result):
    p, eps = result.path, result.eps
    assert p.alphas[0] == 0 and p.alphas[-1] == 1
    steps = np.diff(p.alphas)
    assert np.all(steps >= -1e-12) and np.all(steps <= eps + 1e-9)
    assert p.cost <= result.diagonal.cost + 1e-12
    assert np.allclose(result.diagonal.alphas, result.t)


def test_no_occlusion_output_unchanged_by_texture_quality(far_pair, result):
    """Without occlusions nothing is inpainted: q ≡ 1 (Sec. 5.2) and the frames are those of
    the pipeline before q was measured (reference numbers recorded then, bitwise equal)."""
    pair, k0, k1 = far_pair
    r = result
    np.testing.assert_array_equal(r.q_fwd, np.ones(7))
    np.testing.assert_array_equal(r.q_bwd, np.ones(7))
    assert r.inpainted_fwd is None and r.inpainted_bwd is None
    np.testing.assert_allclose(r.path.alphas, [0, 1 / 9, 1 / 3, 1 / 2, 2 / 3, 8 / 9, 1],
                               atol=1e-12)
    assert r.path.cost == pytest.approx(0.16362139019651042, rel=1e-12)
    assert r.frames.astype(np.float64).sum() == pytest.approx(25566.17536857236, rel=1e-12)
    off = inbetween(k0, k1, pair.skeleton0, pair.skeleton1, 7, animation=pair.animation(7),
                    texture_quality="none")
    np.testing.assert_array_equal(off.frames, r.frames)
    np.testing.assert_array_equal(off.costs.vertex, r.costs.vertex)


def test_beats_cross_dissolve_against_ground_truth(far_pair, result):
    pair, k0, k1 = far_pair
    gt = pair.ground_truth(result.t)
    cd = cross_dissolve(k0, k1, 7)
    mid = 3
    assert metrics.psnr(result.frames[mid], gt[mid]) > metrics.psnr(cd[mid], gt[mid]) + 5
    assert metrics.chamfer(result.frames[mid], gt[mid]) < metrics.chamfer(cd[mid], gt[mid])


def test_interpolated_animation_and_opaque_keys():
    img, sk = bar_drawing(H=200, W=240, y0=120, y1=150)
    rgb = np.where(img[..., 3:4] > 0, img[..., :3], 255).astype(np.uint8)   # paper drawing
    sk1 = bend(sk, -80)
    from physlab.inbetween.evaluate import pose_drawing
    from physlab.inbetween.template import build_template

    key1, _ = pose_drawing(build_template(rgb, sk), sk1)
    key1 = (np.clip(key1[..., :3] * key1[..., 3:] + (1 - key1[..., 3:]), 0, 1) * 255).astype(np.uint8)
    r = inbetween(rgb, key1, sk, sk1, 5, blend="diagonal")    # animation from bone angles
    assert r.frames.shape == (5, 200, 240, 3)                 # RGB in → RGB out, over the paper
    assert np.allclose(r.frames[2][0, 0], 1.0, atol=0.02)     # background = white paper
    assert np.allclose(r.path.alphas, r.t)
    mid = r.skeletons[2]
    assert np.isclose(mid.local_angles()[2], np.radians(-40))  # bone angles interpolated


@pytest.mark.parametrize("deformer", ["lbs", "arap"])
def test_comparison_deformers_run(far_pair, deformer):
    pair, k0, k1 = far_pair
    r = inbetween(k0, k1, pair.skeleton0, pair.skeleton1, 3, deformer=deformer)
    assert r.frames.shape == (3, 128, 128, 4)


def test_bad_inputs(far_pair):
    pair, k0, k1 = far_pair
    s0, s1 = pair.skeleton0, pair.skeleton1
    with pytest.raises(ValueError, match="same size"):
        inbetween(k0, k1[:100], s0, s1, 5)
    other = Skeleton([n + "_x" for n in s1.names], s1.parents, s1.xy)
    with pytest.raises(ValueError, match="different joints"):
        inbetween(k0, k1, s0, other, 5)
    with pytest.raises(ValueError, match="outside"):
        inbetween(k0, k1, s0, s1.with_xy(s1.xy + 500), 5)
    with pytest.raises(ValueError, match="empty"):
        inbetween(k0, k1, s0, s1, 5, mask0=np.zeros(k0.shape[:2], bool))
    with pytest.raises(ValueError, match="n_frames"):
        inbetween(k0, k1, s0, s1, 1)
    with pytest.raises(ValueError, match="expected n_frames"):
        inbetween(k0, k1, s0, s1, 5, animation=pair.animation(4))
    with pytest.raises(ValueError, match="blend"):
        inbetween(k0, k1, s0, s1, 5, blend="best")
    with pytest.raises(ValueError, match="deformer"):
        inbetween(k0, k1, s0, s1, 5, deformer="mls")
    with pytest.raises(ValueError, match="texture_quality must be one of"):
        inbetween(k0, k1, s0, s1, 5, texture_quality=None)
