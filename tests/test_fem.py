"""physlab.fem: Fixed Corotated FEM (PhysAnimator supp. Eqs. 3–6) against independent checks."""
import numpy as np
import pytest

from physlab import fem

RNG = np.random.default_rng(7)


def rot(t):
    return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])


def random_F(n, rng=RNG, inverted_fraction=0.3):
    F = rng.normal(size=(n, 2, 2)) + np.eye(2)
    flip = rng.random(n) < inverted_fraction
    F[flip, :, 0] *= -1  # some with det F < 0
    return F


def square_mesh(k=4):
    u, v = np.meshgrid(np.linspace(0, 1, k + 1), np.linspace(0, 1, k + 1))
    X = np.stack([u.ravel(), v.ravel()], 1)
    idx = np.arange((k + 1) ** 2).reshape(k + 1, k + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    tris = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return X, tris


def test_lame_parameters_plane_strain_and_stress():
    assert fem.lame_parameters(1.0, 0.25) == pytest.approx((0.4, 0.4))
    mu, lam = fem.lame_parameters(1.0, 0.25, plane="stress")
    assert (mu, lam) == pytest.approx((0.4, 0.25 / (1 - 0.0625)))
    with pytest.raises(ValueError, match="Poisson"):
        fem.lame_parameters(1.0, 0.5)
    with pytest.raises(ValueError, match="Young"):
        fem.lame_parameters(-1.0, 0.3)


def test_rest_shape_and_deformation_gradient_of_affine_map():
    X, tris = square_mesh()
    Dm_inv, V = fem.rest_shape(X, tris)
    assert V.sum() == pytest.approx(1.0)
    A, t = np.array([[1.3, 0.4], [-0.2, 0.7]]), np.array([5.0, -2.0])
    F = fem.deformation_gradients(X @ A.T + t, X, tris)  # Eq. (6): F = A for an affine map
    np.testing.assert_allclose(F, np.broadcast_to(A, F.shape), atol=1e-12)
    with pytest.raises(ValueError, match="degenerate"):
        fem.rest_shape(np.array([[0, 0], [1, 0], [2, 0.0]]), np.array([[0, 1, 2]]))


def test_polar_rotation_is_proper_and_matches_svd_with_reflection_fix():
    F = random_F(200)
    R = fem.polar_rotation(F)
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(2), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    U, S, Vt = np.linalg.svd(F)
    D = np.ones((len(F), 2))
    D[:, 1] = np.sign(np.linalg.det(U) * np.linalg.det(Vt))
    R_svd = U @ (D[:, :, None] * Vt)
    np.testing.assert_allclose(R, R_svd, atol=1e-10)
    np.testing.assert_allclose(fem.polar_rotation(np.zeros((1, 2, 2)))[0], np.eye(2))


def test_energy_and_stress_vanish_on_rotations():
    mu, lam = 3.0, 5.0
    R = np.stack([rot(t) for t in np.linspace(-3, 3, 13)])
    np.testing.assert_allclose(fem.fixed_corotated_energy_density(R, mu, lam), 0, atol=1e-12)
    np.testing.assert_allclose(fem.fixed_corotated_stress(R, mu, lam), 0, atol=1e-12)


def test_frame_indifference_and_isotropy():
    mu, lam = 2.0, 7.0
    F = random_F(100)
    Q = rot(0.9)
    psi = fem.fixed_corotated_energy_density(F, mu, lam)
    np.testing.assert_allclose(fem.fixed_corotated_energy_density(Q @ F, mu, lam), psi, rtol=1e-12)
    np.testing.assert_allclose(fem.fixed_corotated_energy_density(F @ Q, mu, lam), psi, rtol=1e-12)
    P = fem.fixed_corotated_stress(F, mu, lam)
    np.testing.assert_allclose(fem.fixed_corotated_stress(Q @ F, mu, lam), Q @ P, atol=1e-11)


def test_stress_is_energy_derivative_by_finite_differences():
    mu, lam = 2.0, 7.0
    F = random_F(60)
    F = F[np.hypot(F[:, 0, 0] + F[:, 1, 1], F[:, 1, 0] - F[:, 0, 1]) > 0.1]  # away from R's kink
    assert np.any(np.linalg.det(F) < 0)
    P = fem.fixed_corotated_stress(F, mu, lam)
    h = 1e-6
    for i in range(2):
        for j in range(2):
            E = np.zeros((2, 2))
            E[i, j] = h
            d = (fem.fixed_corotated_energy_density(F + E, mu, lam)
                 - fem.fixed_corotated_energy_density(F - E, mu, lam)) / (2 * h)
            np.testing.assert_allclose(P[:, i, j], d, rtol=1e-6, atol=1e-6)


def test_stress_matches_torch_autograd():
    torch = pytest.importorskip("torch")
    mu, lam = 1.5, 4.0
    F = random_F(50)
    Ft = torch.tensor(F, requires_grad=True)
    a, b, c, d = Ft[:, 0, 0], Ft[:, 0, 1], Ft[:, 1, 0], Ft[:, 1, 1]
    th = torch.atan2(c - b, a + d)
    R = torch.stack([torch.stack([torch.cos(th), -torch.sin(th)], -1),
                     torch.stack([torch.sin(th), torch.cos(th)], -1)], -2)
    psi = mu * ((Ft - R) ** 2).sum((-2, -1)) + 0.5 * lam * (torch.det(Ft) - 1) ** 2
    (grad,) = torch.autograd.grad(psi.sum(), Ft)
    np.testing.assert_allclose(fem.fixed_corotated_stress(F, mu, lam), grad.numpy(), atol=1e-10)


def test_stress_derivative_by_finite_differences():
    mu, lam = 2.0, 7.0
    F = random_F(20)
    dP = fem.fixed_corotated_stress_derivative(F, mu, lam)
    h = 1e-6
    for k in range(2):
        for l in range(2):
            E = np.zeros((2, 2))
            E[k, l] = h
            d = (fem.fixed_corotated_stress(F + E, mu, lam) - fem.fixed_corotated_stress(F - E, mu, lam)) / (2 * h)
            np.testing.assert_allclose(dP[:, :, :, k, l], d, atol=1e-5)


def fd_gradient(fun, x, h=1e-6):
    g = np.zeros_like(x)
    for idx in np.ndindex(x.shape):
        e = np.zeros_like(x)
        e[idx] = h
        g[idx] = (fun(x + e) - fun(x - e)) / (2 * h)
    return g


def test_forces_are_minus_energy_gradient_and_fast_path_agrees():
    X, tris = square_mesh(3)
    mu = RNG.uniform(1, 3, len(tris))  # per-triangle materials
    lam = RNG.uniform(2, 6, len(tris))
    x = X @ np.array([[1.2, 0.3], [-0.1, 0.8]]).T + 0.08 * RNG.normal(size=X.shape)
    x[5] = x[0] + (x[0] - x[5])  # fold a vertex over: some inverted triangles
    f = fem.elastic_forces(x, X, tris, mu, lam)
    np.testing.assert_allclose(f, -fd_gradient(lambda y: fem.elastic_energy(y, X, tris, mu, lam), x),
                               atol=1e-5)
    model = fem.CorotatedFEM(X, tris, mu, lam)
    np.testing.assert_allclose(model.forces(x), f, atol=1e-12)
    assert model.energy(x) == pytest.approx(fem.elastic_energy(x, X, tris, mu, lam), rel=1e-12)


def test_forces_sum_to_zero_with_zero_torque_and_pass_patch_tests():
    X, tris = square_mesh(5)
    x = X + 0.1 * RNG.normal(size=X.shape)
    f = fem.elastic_forces(x, X, tris, 3.0, 4.0)
    np.testing.assert_allclose(f.sum(0), 0, atol=1e-12)
    assert abs(np.sum(x[:, 0] * f[:, 1] - x[:, 1] * f[:, 0])) < 1e-11
    # rigid motion: zero force everywhere
    np.testing.assert_allclose(fem.elastic_forces(X @ rot(1.1).T + 3.0, X, tris, 3.0, 4.0), 0, atol=1e-12)
    # uniform stretch: interior vertices feel no net force (patch test)
    f = fem.elastic_forces(X @ np.diag([1.3, 0.9]), X, tris, 3.0, 4.0)
    interior = np.all((X > 1e-9) & (X < 1 - 1e-9), axis=1)
    np.testing.assert_allclose(f[interior], 0, atol=1e-12)
    assert np.abs(f[~interior]).max() > 0.1


def test_reference_number_uniaxial_stretch():
    # single right triangle stretched by s along x: Ψ = μ (s-1)² + λ/2 (s-1)², V = 1/2
    X = np.array([[0, 0], [1, 0], [0, 1.0]])
    tris = np.array([[0, 1, 2]])
    s, mu, lam = 1.5, 2.0, 3.0
    assert fem.elastic_energy(X * [s, 1], X, tris, mu, lam) == pytest.approx(0.5 * (mu + lam / 2) * 0.25)
    f = fem.elastic_forces(X * [s, 1], X, tris, mu, lam)
    # P = diag(2μ(s-1) + λ(s-1), λ(s-1) s) ; f1 = -V P Dm^-T e1 = -(1/2) P[:, 0]
    np.testing.assert_allclose(f[1], [-0.5 * (2 * mu + lam) * (s - 1), 0.0], atol=1e-12)


def test_lumped_masses_sum_to_rho_area():
    # hand case: two right triangles of area 1/2 sharing the diagonal (0, 2) of the unit square
    m = fem.lumped_masses(np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]), np.array([[0, 1, 2], [0, 2, 3]]), 6.0)
    np.testing.assert_allclose(m, [2.0, 1.0, 2.0, 1.0])  # ρ V / 3 = 1 per triangle corner
    X, tris = square_mesh(4)
    m = fem.lumped_masses(X * 2.0, tris, rho=3.0)
    assert m.sum() == pytest.approx(3.0 * 4.0)
    assert m.min() > 0
    with pytest.raises(ValueError, match="rho"):
        fem.lumped_masses(X, tris, rho=0.0)


def test_collapsed_triangles_give_finite_forces():
    X, tris = square_mesh(2)
    x = X.copy()
    x[:] = x.mean(0)  # every triangle collapsed to a point (F = 0)
    assert np.all(np.isfinite(fem.elastic_forces(x, X, tris, 1.0, 1.0)))
    x = X * [1.0, 0.0]  # all collapsed onto a line (det F = 0)
    assert np.all(np.isfinite(fem.CorotatedFEM(X, tris, 1.0, 1.0).forces(x)))


def test_inverted_triangle_recovers_orientation():
    X = np.array([[0, 0], [1, 0], [0, 1.0]])
    tris = np.array([[0, 1, 2]])
    x = X.copy()
    x[2] = (0.2, -0.6)  # vertex 2 pushed through the opposite edge: det F < 0
    model = fem.CorotatedFEM(X, tris, *fem.lame_parameters(50.0, 0.3))
    m = fem.lumped_masses(X, tris, 1.0)
    v = np.zeros_like(x)
    dt = 0.5 * fem.stable_time_step(X, tris, 50.0, 0.3, 1.0)
    assert np.linalg.det(model.deformation_gradients(x))[0] < 0
    for _ in range(4000):  # semi-implicit Euler (PhysAnimator Eq. 7) with light damping
        v += dt * (model.forces(x) / m[:, None] - 2.0 * v)
        x += dt * v
    assert np.linalg.det(model.deformation_gradients(x))[0] > 0.5


def test_stable_time_step_scales_with_mesh_and_stiffness():
    X, tris = square_mesh(4)
    dt1 = fem.stable_time_step(X, tris, 100.0, 0.3, 1.0)
    # and it is stable: undamped semi-implicit Euler at the estimate stays bounded
    model = fem.CorotatedFEM(X, tris, *fem.lame_parameters(100.0, 0.3))
    m = fem.lumped_masses(X, tris, 1.0)
    x, v = X + 0.01 * RNG.normal(size=X.shape), np.zeros_like(X)
    for _ in range(3000):
        v += dt1 * model.forces(x) / m[:, None]
        x += dt1 * v
    assert np.abs(x - X).max() < 0.1
    assert fem.stable_time_step(2 * X, tris, 100.0, 0.3, 1.0) == pytest.approx(2 * dt1)
    assert fem.stable_time_step(X, tris, 400.0, 0.3, 1.0) == pytest.approx(dt1 / 2)


def test_stiffness_matrix_is_force_derivative_and_symmetric():
    X, tris = square_mesh(3)
    mu, lam = fem.lame_parameters(100.0, 0.3)
    x = X @ np.array([[1.1, 0.2], [-0.1, 0.9]]).T + 0.05 * RNG.normal(size=X.shape)
    K = fem.elastic_stiffness(x, X, tris, mu, lam).toarray()
    h = 1e-6
    K_fd = np.zeros_like(K)
    for idx in range(2 * len(X)):
        e = np.zeros(2 * len(X))
        e[idx] = h
        fp = fem.elastic_forces(x + e.reshape(-1, 2), X, tris, mu, lam).ravel()
        fm = fem.elastic_forces(x - e.reshape(-1, 2), X, tris, mu, lam).ravel()
        K_fd[:, idx] = (fp - fm) / (2 * h)
    np.testing.assert_allclose(K, K_fd, atol=1e-4 * np.abs(K).max())
    np.testing.assert_allclose(K, K.T, atol=1e-10 * np.abs(K).max())  # Hessian of an energy
    t = np.tile([1.0, -2.0], len(X))  # translations are in its null space
    np.testing.assert_allclose(K @ t, 0, atol=1e-9)
