"""Symmetric Dirichlet energy and the Sobolev-preconditioned deformer (Brodt & Bessmeltsev Eq. 1)."""
import numpy as np
import pytest
from _drawings import bar_drawing, bend

from physlab.inbetween.deform import (SymmetricDirichletDeformer, deform, flipped_count,
                                      max_injective_step, symmetric_dirichlet_density,
                                      symmetric_dirichlet_energy, symmetric_dirichlet_gradient)
from physlab.inbetween.template import build_template
from physlab.mesh import grid_mesh


def rot(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


@pytest.fixture(scope="module")
def bar():
    img, sk = bar_drawing()
    return build_template(img, sk), sk


def test_energy_is_four_for_rigid_motions_and_larger_otherwise():
    m = grid_mesh(4, 3, 40.0, 30.0)
    X, tris = m.X, m.tris
    assert np.isclose(symmetric_dirichlet_energy(X, tris, X), 4.0)  # 4 Σ A_f, Σ A_f = 1
    for th in (0.3, 2.0, -2.9):
        x = X @ rot(th).T + [5.0, -7.0]
        assert np.isclose(symmetric_dirichlet_energy(X, tris, x), 4.0)
    assert symmetric_dirichlet_energy(X, tris, 1.2 * X) > 4.0
    shear = X @ np.array([[1.0, 0.3], [0.0, 1.0]]).T
    assert symmetric_dirichlet_energy(X, tris, shear) > 4.0
    # analytic: uniform scale s gives 2 s² + 2 / s²
    assert np.isclose(symmetric_dirichlet_energy(X, tris, 2.0 * X), 2 * 4 + 2 / 4)
    flipped = X * [1.0, -1.0]
    assert symmetric_dirichlet_energy(X, tris, flipped) == np.inf
    J = np.stack([rot(0.7), np.diag([2.0, 0.5])])
    assert np.allclose(symmetric_dirichlet_density(J), [4.0, 4 + 0.25 + 4 + 0.25])


def test_gradient_matches_finite_differences():
    m = grid_mesh(3, 3, 30.0, 30.0)
    X, tris = m.X, m.tris
    rng = np.random.default_rng(1)
    x = X @ rot(0.4).T * 1.1 + rng.normal(0, 1.0, X.shape)
    g = symmetric_dirichlet_gradient(X, tris, x)
    h = 1e-6
    fd = np.zeros_like(x)
    for i in range(x.shape[0]):
        for k in range(2):
            e = np.zeros_like(x)
            e[i, k] = h
            fd[i, k] = (symmetric_dirichlet_energy(X, tris, x + e)
                        - symmetric_dirichlet_energy(X, tris, x - e)) / (2 * h)
    assert np.allclose(g, fd, rtol=1e-5, atol=1e-9)
    assert np.allclose(symmetric_dirichlet_gradient(X, tris, X), 0.0, atol=1e-12)
    # the solver's energy, written per 2x2 entry (s (1 + 1/det^2)), equals the matrix form
    # sum A (|J|^2 + |J^-1|^2) of symmetric_dirichlet_energy
    from physlab.inbetween.deform import _normalised_areas, _sd_energy_grad

    Dm_inv, A = _normalised_areas(X, tris)
    e, g2 = _sd_energy_grad(x, np.asarray(tris), Dm_inv, A, len(X))
    assert e == pytest.approx(symmetric_dirichlet_energy(X, tris, x), rel=1e-13)
    np.testing.assert_array_equal(g2, g)


def test_max_injective_step_single_triangle():
    X = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    tris = np.array([[0, 1, 2]])
    d = np.array([[0.0, 0.0], [0.0, 0.0], [0.0, -2.0]])  # apex moves down: flat at α = 0.5
    assert np.isclose(max_injective_step(X, d, tris), 0.5)
    assert max_injective_step(X, -d, tris) == np.inf
    # quadratic case: det = (1 − α)(1 − α) → root 1
    d2 = np.array([[0.0, 0.0], [-1.0, 0.0], [0.0, -1.0]])
    assert np.isclose(max_injective_step(X, d2, tris), 1.0)


def test_handles_at_rest_return_the_rest_mesh(bar):
    tpl, sk = bar
    res = SymmetricDirichletDeformer(tpl).solve(sk)
    assert res.iterations == 0 and res.converged
    assert np.array_equal(res.x, tpl.X)


def test_rigid_handle_motion_gives_rigid_result(bar):
    tpl, sk = bar
    R, t = rot(np.radians(60)), np.array([20.0, -10.0])
    posed = sk.with_xy(sk.xy @ R.T + t)
    target = tpl.X @ R.T + t
    x = deform(tpl, posed)  # default tolerance: the energy is within ~1e-4 of the optimum
    assert np.abs(x - target).max() < 0.5
    assert np.isclose(symmetric_dirichlet_energy(tpl.X, tpl.tris, x), 4.0, atol=1e-4)
    x = deform(tpl, posed, tol=1e-6)
    assert np.abs(x - target).max() < 0.01


@pytest.mark.parametrize("degrees", [90, 150])
def test_large_bends_stay_injective_and_reach_the_handles(bar, degrees):
    tpl, sk = bar
    D = SymmetricDirichletDeformer(tpl)
    x = None
    for s in np.linspace(0, 1, 5)[1:]:  # warm start along the motion, as the pipeline does
        res = D.solve(bend(sk, degrees * s), x0=x)
        x = res.x
        assert res.converged
        assert flipped_count(tpl.X, x, tpl.tris) == 0
    assert res.handle_error.max() < 1.0  # px, μ = 200
    assert res.energy_d > 4.0


def test_sobolev_preconditioning_needs_far_fewer_iterations(bar):
    tpl, sk = bar
    target = bend(sk, 60)
    its = {}
    for pre, method in (("sobolev", "lbfgs"), ("sobolev", "gradient"), ("none", "gradient")):
        res = SymmetricDirichletDeformer(tpl, preconditioner=pre).solve(
            target, method=method, max_iter=1000)
        its[pre, method] = res.iterations if res.converged else np.inf
    assert its["sobolev", "lbfgs"] < its["sobolev", "gradient"] < its["none", "gradient"]
    assert its["none", "gradient"] == np.inf  # plain gradient descent: not even close


def test_bad_inputs(bar):
    tpl, sk = bar
    D = SymmetricDirichletDeformer(tpl)
    with pytest.raises(ValueError, match="one per handle"):
        D.solve(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="NaN"):
        D.solve(np.full((len(tpl.handle_tris), 2), np.nan))
    flipped = tpl.X * [1.0, -1.0]
    with pytest.raises(ValueError, match="flipped"):
        D.solve(sk, x0=flipped)
    with pytest.raises(ValueError, match="method"):
        D.solve(sk, method="newton")
    with pytest.raises(ValueError, match="preconditioner"):
        SymmetricDirichletDeformer(tpl, preconditioner="jacobi")
    with pytest.raises(ValueError, match="flipped"):
        symmetric_dirichlet_gradient(tpl.X, tpl.tris, flipped)
