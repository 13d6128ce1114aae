"""Tests of physlab.inbetween.blend: image matrix, quality terms, α grid, shortest path."""
import itertools

import numpy as np
import pytest

from physlab.inbetween.blend import (BlendCosts, BlendPath, ImageMatrix, alpha_grid, blend_costs,
                                     blending_path, diagonal_path, image_matrix,
                                     interpolation_quality, path_cost, render_path, row_flows,
                                     select_frames, texture_quality)
from physlab.inbetween.frame_interpolation import CrossDissolve, FlowInterpolator


# --------------------------------------------------------------------------- helpers
def dp_optimum(costs, eps):
    """Reference: dynamic programming over the layered graph (Bellman), O(n_t n_α²)."""
    al, V = costs.alphas, costs.vertex
    n_t, n_a = V.shape
    dA = al[None, :] - al[:, None]                                   # (k, m): α_m − α_k
    ok = (dA >= -1e-12) & (dA <= eps + 1e-9)
    best = np.full(n_a, np.inf)
    best[0] = V[0, 0]
    for i in range(n_t - 1):
        step = np.where(ok, best[:, None] + costs.move[i] * dA, np.inf)
        best = step.min(axis=0) + V[i + 1]
    return best[-1]


def brute_force(costs, eps):
    """Reference: enumerate every index sequence with fixed ends."""
    al, n_a = costs.alphas, len(costs.alphas)
    best = np.inf
    for mid in itertools.product(range(n_a), repeat=costs.n_t - 2):
        idx = np.array((0,) + mid + (n_a - 1,))
        d = np.diff(al[idx])
        if np.all(d >= -1e-12) and np.all(d <= eps + 1e-9):
            best = min(best, path_cost(costs, idx))
    return best


def check_path(p, costs, eps):
    n_t = costs.n_t
    assert isinstance(p, BlendPath)
    assert p.indices.shape == (n_t,) and p.alphas.shape == (n_t,)     # one vertex per row
    assert p.indices[0] == 0 and p.indices[-1] == len(costs.alphas) - 1
    assert p.alphas[0] == 0.0 and p.alphas[-1] == 1.0
    d = np.diff(p.alphas)
    assert np.all(d >= 0) and np.all(d <= eps + 1e-9)
    np.testing.assert_array_equal(p.alphas, costs.alphas[p.indices])
    assert p.cost == pytest.approx(path_cost(costs, p.indices), abs=1e-12)


# --------------------------------------------------------------------------- α grid
def test_alpha_grid():
    al, eps = alpha_grid(11)
    assert len(al) == 31 and eps == pytest.approx(0.3)
    t = np.linspace(0, 1, 11)
    assert np.all(np.min(np.abs(al[:, None] - t[None]), axis=0) < 1e-12)   # diagonal on grid
    h = al[1] - al[0]
    assert eps / h == pytest.approx(round(eps / h))
    al, eps = alpha_grid(2)
    assert eps == 1.0 and len(al) == 4
    al, eps = alpha_grid(5, speedup=1)
    np.testing.assert_allclose(al, np.linspace(0, 1, 5))
    assert eps == pytest.approx(0.25)
    al, eps = alpha_grid(11, speedup=2.5, subdivisions=2)
    assert eps == pytest.approx(0.25) and len(al) == 21
    with pytest.raises(ValueError, match="speedup must be ≥ 1"):
        alpha_grid(11, speedup=0.5)
    with pytest.raises(ValueError, match="integer"):
        alpha_grid(11, speedup=2.5, subdivisions=1)
    with pytest.raises(ValueError, match="n_frames"):
        alpha_grid(1)


# --------------------------------------------------------------------------- Q and q
def test_interpolation_quality_analytic():
    H, W = 20, 30
    yy, xx = np.mgrid[0:H, 0:W].astype(float)
    trans = np.stack([np.full((H, W), 2.5), np.full((H, W), -1.0)], -1)
    rot = 0.1 * np.stack([-(yy - 7), xx - 11], -1)
    s = 0.05
    scale = s * np.stack([xx - 11, yy - 7], -1)
    assert interpolation_quality(trans) == 0
    assert interpolation_quality(rot) == pytest.approx(0, abs=1e-24)   # incompressible
    assert interpolation_quality(scale) == pytest.approx(4 * s * s, rel=1e-12)  # div = 2s
    # batch + mask: the scaling only inside a box, Q over the box is still 4 s²
    mask = np.zeros((H, W), bool)
    mask[5:15, 5:25] = True
    part = np.where(mask[..., None], scale, 0.0)
    inner = np.zeros_like(mask)
    inner[6:14, 6:24] = True
    Q = interpolation_quality(np.stack([trans, part]), np.stack([inner, inner]))
    np.testing.assert_allclose(Q, [0, 4 * s * s], rtol=1e-12)
    assert interpolation_quality(scale, np.zeros((H, W), bool)) == 0   # empty mask
    # a sine flow: central differences give div = sin(k) cos(kx) inside, so Q ≈ ½ sin²(k)
    # (one-sided differences at the two border columns); fixed reference number
    k = 2 * np.pi * 3 / W
    v = np.stack([np.sin(k * xx), 0 * yy], -1)
    assert interpolation_quality(v) == pytest.approx(0.5 * np.sin(k) ** 2, rel=0.02)
    assert interpolation_quality(v) == pytest.approx(0.1696070476380377, rel=1e-12)
    with pytest.raises(ValueError, match="shape"):
        interpolation_quality(np.zeros((4, 4, 3)))
    with pytest.raises(ValueError, match="mask"):
        interpolation_quality(scale, mask[:5])


def test_texture_quality():
    np.testing.assert_array_equal(texture_quality(n_t=4), np.ones(4))
    F = np.zeros((3, 10, 10), bool)
    F[:, :, :] = True
    A = np.zeros_like(F)
    A[1, :5, :5] = True                     # 25 of 100 visible pixels inpainted
    A[2, :, :] = True
    np.testing.assert_allclose(texture_quality(A, F), [1.0, 0.75, 0.0])
    np.testing.assert_allclose(texture_quality([None, A[1], None], F), [1.0, 0.75, 1.0])
    with pytest.raises(ValueError, match="foreground"):
        texture_quality(A)
    with pytest.raises(ValueError, match="n_t"):
        texture_quality()
    with pytest.raises(ValueError, match=r"inpainted\[1\] has shape"):
        texture_quality([A[0], A[1, :5]], F[:2])
    with pytest.raises(ValueError, match="inpainted has 3 masks but foreground 2"):
        texture_quality(A, F[:2])


# --------------------------------------------------------------------------- costs
def test_blend_costs_shapes_and_values():
    al, _ = alpha_grid(5)
    c = blend_costs(al, distortion_fwd=[0, 0.1, 0.2, 0.3, 0.4], q_bwd=[0.5, 1, 1, 1, 1],
                    Q=[1, 2, 4, 2, 1], lambda_diag=0, texture_model="linear")
    assert c.vertex.shape == (5, len(al)) and c.move.shape == (4,)
    # row 1: c = ((1 − α)·0.1 + α·0) / 4
    np.testing.assert_allclose(c.vertex[1], (1 - al) * 0.1 / 4)
    np.testing.assert_allclose(c.vertex[0], al * 0.5 / 4)
    np.testing.assert_allclose(c.move, [0.375, 0.75, 0.75, 0.375])       # ½(Q̂_i + Q̂_i+1)
    with pytest.raises(ValueError, match=r"shape \(5,\)"):
        blend_costs(al, Q=[1, 2, 3, 4, 5], q_fwd=[1, 1])
    with pytest.raises(ValueError, match="≥ 0"):
        blend_costs(al, distortion_fwd=-np.ones(5))
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        blend_costs(al, q_fwd=2 * np.ones(5))
    with pytest.raises(ValueError, match="n_t"):
        blend_costs(al)
    with pytest.raises(ValueError, match="texture_model"):
        blend_costs(al, n_t=5, texture_model="quadratic")


def test_variance_texture_model_values():
    al, _ = alpha_grid(5)
    Df = np.array([0, 0.1, 0.2, 0.3, 0.4])
    c = blend_costs(al, distortion_fwd=Df, lambda_diag=0, prior=0.01)
    t = np.linspace(0, 1, 5)
    vf, vb = Df + 0.01 * t, 0.01 * (1 - t)                  # σ→², σ←²
    expect = ((1 - al[None]) ** 2 * vf[:, None] + al[None] ** 2 * vb[:, None]) / vf.max() / 4
    np.testing.assert_allclose(c.vertex, expect)
    # per row, the cheapest α is the minimum-variance blend σ→² / (σ→² + σ←²)
    best = al[np.argmin(c.vertex, axis=1)]
    np.testing.assert_allclose(best, vf / (vf + vb), atol=0.5 * (al[1] - al[0]) + 1e-12)


# --------------------------------------------------------------------------- paths
def test_default_costs_choose_the_diagonal():
    n = 11
    al, eps = alpha_grid(n)
    c = blend_costs(al, n_t=n, texture_model="linear")
    p = blending_path(c, eps)
    check_path(p, c, eps)
    np.testing.assert_allclose(p.alphas, np.linspace(0, 1, n), atol=1e-12)
    assert p.cost == p.diagonal_cost == pytest.approx(0.0, abs=1e-15)
    # the variance model without distortion information: σ→² ∝ t, σ←² ∝ 1 − t → α* = t
    c = blend_costs(al, n_t=n)
    p = blending_path(c, eps)
    check_path(p, c, eps)
    np.testing.assert_allclose(p.alphas, np.linspace(0, 1, n), atol=1e-12)
    assert p.cost == pytest.approx(p.diagonal_cost)


def test_path_prefers_less_distorted_key():
    n = 11
    al, eps = alpha_grid(n)
    # key 0's texture is stretched throughout: leave it as fast as ε allows
    c = blend_costs(al, distortion_fwd=np.full(n, 0.3), texture_model="linear")
    p = blending_path(c, eps)
    np.testing.assert_allclose(p.alphas, np.minimum(1, eps * np.arange(n)), atol=1e-12)
    # variance model: lean on key 1 but keep blending (α* = σ→²/(σ→² + σ←²) ≈ 0.97)
    pv = blending_path(blend_costs(al, distortion_fwd=np.full(n, 0.3)), eps)
    assert pv.alphas[3] == pytest.approx(0.9) and pv.cost < pv.diagonal_cost
    # symmetric distortion growing away from each key: hold key 0, switch mid-way, hold key 1
    D = np.linspace(0, 0.5, n)
    c = blend_costs(al, distortion_fwd=D, distortion_bwd=D[::-1], texture_model="linear")
    p = blending_path(c, eps)
    check_path(p, c, eps)
    assert np.all(p.alphas[:4] == 0) and np.all(p.alphas[-4:] == 1)
    assert p.alphas[5] == pytest.approx(0.5)
    assert p.cost < p.diagonal_cost
    # fwd texture inpainted from t = 0.4 on: switch to bwd before that
    q = np.ones(n)
    q[4:] = 0.7
    p = blending_path(blend_costs(al, q_fwd=q, texture_model="linear"), eps)
    assert p.alphas[4] == 1.0


def test_inpainted_key_texture_moves_the_blend_to_the_other_key():
    """Sec. 5.2: where key 0's deformed texture shows an inpainted region and key 1's does not,
    q(I→) < 1 and the cheapest path leans on key 1 there (a larger α than with q ≡ 1)."""
    n, H, W = 11, 20, 20
    al, eps = alpha_grid(n)
    F = np.ones((n, H, W), bool)                            # the visible silhouettes
    A0 = np.zeros((n, H, W), bool)
    A0[3:8, :, :10] = True                                  # half of I→ inpainted at t = .3–.7
    q0 = texture_quality(A0, F)
    q1 = texture_quality(np.zeros_like(A0), F)              # key 1's texture: nothing inpainted
    expect = np.ones(n)
    expect[3:8] = 0.5
    np.testing.assert_array_equal(q0, expect)
    np.testing.assert_array_equal(q1, np.ones(n))
    t = np.linspace(0, 1, n)
    opts = dict(distortion_fwd=0.02 * t, distortion_bwd=0.02 * (1 - t))   # some distortion
    for model in ("variance", "linear"):
        base = blending_path(blend_costs(al, texture_model=model, **opts), eps)
        with_q = blending_path(blend_costs(al, q_fwd=q0, q_bwd=q1, texture_model=model,
                                           **opts), eps)
        assert np.all(with_q.alphas >= base.alphas - 1e-12), model
        up = base.alphas[3:8] < 1                                        # room to move
        assert up.sum() >= 3, model
        assert np.all(with_q.alphas[3:8][up] > base.alphas[3:8][up]), model   # towards key 1
    # variance model, per row: the minimum-variance α* = σ→²/(σ→² + σ←²) moves up
    # exactly where q0 < 1
    c1 = blend_costs(al, **opts).vertex
    cq = blend_costs(al, q_fwd=q0, q_bwd=q1, **opts).vertex
    moved = al[np.argmin(cq, axis=1)] - al[np.argmin(c1, axis=1)]
    assert np.all(moved[3:8] > 0) and np.all(moved[:3] == 0) and np.all(moved[8:] == 0)
    # q ≡ 1 is the default
    base = blending_path(blend_costs(al, q_fwd=np.ones(n), q_bwd=q1, **opts), eps)
    np.testing.assert_array_equal(base.alphas, blending_path(blend_costs(al, **opts), eps).alphas)
    # variance model, reference numbers at t = 0.5: α = 0.5 with q ≡ 1; with q0 = 0.5 the grid
    # value nearest σ→²/(σ→² + σ←²) = (0.5 + 0.01 + 0.005)/(0.515 + 0.015) = 0.972
    assert base.alphas[5] == pytest.approx(0.5)
    mid = blending_path(blend_costs(al, q_fwd=q0, **opts), eps).alphas[5]
    assert mid == pytest.approx(29 / 30, abs=1e-12)


def test_path_moves_where_flow_is_incompressible():
    n = 11
    al, eps = alpha_grid(n)
    Q = np.ones(n)
    Q[7:10] = 0.1
    c = blend_costs(al, Q=Q, texture_model="linear")
    p = blending_path(c, eps)
    check_path(p, c, eps)
    np.testing.assert_allclose(p.alphas, [0, 0, 0, 0, 0, 0, 0, 0.3, 0.6, 0.9, 1.0], atol=1e-12)
    # Q term: 0.4 of α on the two edges with Q̂-mean 0.55, 0.6 on those with 0.1; the rest
    # is the λ_diag tie-break (reference number)
    assert p.cost == pytest.approx(0.4 * 0.55 + 0.6 * 0.1, abs=1e-3)
    assert p.cost == pytest.approx(0.28027, rel=1e-9)
    assert p.cost < p.diagonal_cost


def test_random_costs_match_exhaustive_and_dp():
    rng = np.random.default_rng(0)
    exhaustive = 0
    for trial in range(60):
        n_t = int(rng.integers(2, 8))
        speedup = int(rng.integers(1, 4))
        al, eps = alpha_grid(n_t, speedup=speedup, subdivisions=int(rng.integers(1, 3)))
        V = rng.random((n_t, len(al)))
        if trial % 3 == 0:
            V -= 0.5                                                  # negative costs too
        if trial % 5 == 0:
            V[:] = 0.0                                                # all-zero edges survive
        c = BlendCosts(vertex=V, move=rng.random(n_t - 1) * 2, alphas=al)
        p = blending_path(c, eps)
        check_path(p, c, eps)
        assert p.cost <= p.diagonal_cost + 1e-12
        assert p.cost == pytest.approx(dp_optimum(c, eps), abs=1e-12)
        if len(al) ** max(n_t - 2, 0) <= 400:
            assert p.cost == pytest.approx(brute_force(c, eps), abs=1e-12)
            exhaustive += 1
    assert exhaustive >= 20


def test_diagonal_path_and_path_cost():
    al, _ = alpha_grid(5)
    d = diagonal_path(5, al)
    np.testing.assert_allclose(d.alphas, np.linspace(0, 1, 5))
    assert np.isnan(d.cost)
    c = BlendCosts(vertex=np.ones((5, len(al))), move=np.full(4, 2.0), alphas=al)
    assert diagonal_path(5, al, c).cost == pytest.approx(5 + 2)
    assert path_cost(c, np.array([0, 0, 0, 0, len(al) - 1])) == pytest.approx(5 + 2)
    with pytest.raises(ValueError, match="diagonal"):
        diagonal_path(4, np.linspace(0, 1, 5))


def test_path_errors():
    al, _ = alpha_grid(11)
    c = blend_costs(al, n_t=11)
    with pytest.raises(ValueError, match="no path over 11 rows"):
        blending_path(c, 0.09)
    # enough ε in total, but the grid is too coarse to take any step
    c = BlendCosts(vertex=np.zeros((5, 3)), move=np.zeros(4), alphas=[0, 0.5, 1])
    with pytest.raises(ValueError, match="no monotone path"):
        blending_path(c, 0.3)
    with pytest.raises(ValueError, match="vertex must have shape"):
        BlendCosts(vertex=np.zeros((5, 4)), move=np.zeros(4), alphas=[0, 0.5, 1])
    with pytest.raises(ValueError, match="move must have shape"):
        BlendCosts(vertex=np.zeros((5, 3)), move=np.zeros(3), alphas=[0, 0.5, 1])
    with pytest.raises(ValueError, match="NaN"):
        BlendCosts(vertex=np.full((5, 3), np.nan), move=0.0, alphas=[0, 0.5, 1])
    with pytest.raises(ValueError, match="from 0 to 1"):
        BlendCosts(vertex=np.zeros((5, 3)), move=0.0, alphas=[0.1, 0.5, 1])
    with pytest.raises(TypeError, match="ImageMatrix"):
        blending_path(c, 0.5, distortion_fwd=np.zeros(5))
    with pytest.raises(TypeError):
        blending_path(np.zeros((5, 3)), 0.5)
    with pytest.raises(ValueError, match="eps"):
        blending_path(c, -1)


# --------------------------------------------------------------------------- the matrix
def _blob_sequences(n_t=5, n=40):
    """Two differently textured copies of one moving ellipse: (n_t, n, n, 4) each."""
    yy, xx = np.mgrid[0:n, 0:n].astype(float)
    fwd, bwd = [], []
    for t in np.linspace(0, 1, n_t):
        cx, cy = 15 + 8 * t, 20
        a = (np.hypot((xx - cx) / 10, (yy - cy) / 7) < 1).astype(np.float32)
        f = np.zeros((n, n, 4), np.float32)
        b = np.zeros((n, n, 4), np.float32)
        f[..., 0] = 0.5 + 0.4 * np.sin((xx - cx) * 0.8)
        f[..., 1] = 0.3
        b[..., 2] = 0.5 + 0.4 * np.cos((yy - cy) * 0.9)
        b[..., 1] = 0.6
        f[..., 3] = b[..., 3] = a
        fwd.append(f)
        bwd.append(b)
    return np.stack(fwd), np.stack(bwd)


@pytest.mark.parametrize("interp", [CrossDissolve(), FlowInterpolator()], ids=["cd", "flow"])
def test_image_matrix_rows_and_path_frames(interp):
    fwd, bwd = _blob_sequences()
    al, eps = alpha_grid(5, speedup=2, subdivisions=2)
    M = image_matrix(fwd, bwd, al, interpolator=interp)
    assert isinstance(M, ImageMatrix)
    assert M.images.shape == (5, 9, 40, 40, 4) and M.images.dtype == np.float32
    assert M.flows.shape == (5, 40, 40, 2) and M.flows.dtype == np.float32
    np.testing.assert_allclose(M.t, np.linspace(0, 1, 5))
    np.testing.assert_array_equal(M.images[:, 0], fwd)             # I(0, t) = I→(t)
    np.testing.assert_array_equal(M.images[:, -1], bwd)            # I(1, t) = I←(t)
    np.testing.assert_array_equal(M.flows, row_flows(fwd, bwd, interp))
    D = np.linspace(0, 0.4, 5)
    p = blending_path(M, eps, distortion_fwd=D, distortion_bwd=D[::-1])
    assert p.alphas[0] == 0 and p.alphas[-1] == 1
    frames = select_frames(M, p)
    assert frames.shape == (5, 40, 40, 4)
    np.testing.assert_array_equal(frames[0], fwd[0])
    np.testing.assert_array_equal(frames[-1], bwd[-1])
    np.testing.assert_array_equal(render_path(fwd, bwd, p, interp), frames)


def test_image_matrix_without_interpolate_and_flow():
    class Minimal:                                   # only the protocol's two methods
        def __call__(self, img0, img1, alphas):
            return CrossDissolve()(img0, img1, alphas)

        def flow(self, img0, img1):
            return np.ones(np.shape(img0)[:2] + (2,), np.float32)

    fwd, bwd = _blob_sequences(n_t=3, n=12)
    M = image_matrix(list(fwd), list(bwd), np.linspace(0, 1, 5), interpolator=Minimal())
    assert M.images.shape == (3, 5, 12, 12, 4)
    np.testing.assert_array_equal(M.flows, 1.0)


def test_image_matrix_errors():
    fwd, bwd = _blob_sequences(n_t=3, n=12)
    with pytest.raises(ValueError, match="same shape"):
        image_matrix(fwd, bwd[:2], np.linspace(0, 1, 3))
    with pytest.raises(ValueError, match="from 0 to 1"):
        image_matrix(fwd, bwd, [0, 0.7, 0.5, 1])
    with pytest.raises(ValueError, match="at least 2 frames"):
        image_matrix(fwd[:1], bwd[:1], [0, 1])
    with pytest.raises(ValueError, match="one per row"):
        render_path(fwd, bwd, [0, 1])
    M = image_matrix(fwd, bwd, [0, 0.5, 1], interpolator=CrossDissolve())
    with pytest.raises(ValueError, match="indices"):
        select_frames(M, np.array([0, 1, 5]))
