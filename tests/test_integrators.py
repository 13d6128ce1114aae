"""physlab.integrators: orders of accuracy, stability, Newton, pinning, error messages."""
import numpy as np
import pytest
import scipy.sparse as sp

from physlab import springs
from physlab.integrators import (
    MECHANICAL_METHODS, MECHANICAL_STEPS, METHODS, ORDER, STEPS, ConvergenceError, LinearSolver,
    SimulationDiverged, convergence_order, finite_difference_jacobian, integrate,
    mechanical_explicit_euler_step, mechanical_implicit_euler_step,
    mechanical_semi_implicit_euler_step, newton_solve, simulate, stability_function,
)


def oscillator(t, y):  # x'' = -x as y = (x, v): exact x = cos t
    return np.array([y[1], -y[0]])


def oscillator_jac(t, y):
    return np.array([[0.0, 1.0], [-1.0, 0.0]])


def riccati(t, y):  # y' = -2 t y^2, y(0) = 1: exact y = 1 / (1 + t^2) (nonlinear, time-dependent)
    return -2 * t * y**2


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("problem", ["oscillator", "riccati"])
def test_measured_order_matches_theory(method, problem):
    f, y0, exact = {
        "oscillator": (oscillator, [1.0, 0.0], lambda t: np.cos(t)),
        "riccati": (riccati, [1.0], lambda t: 1 / (1 + t**2)),
    }[problem]
    dts = [0.1, 0.05, 0.025, 0.0125] if ORDER[method] < 4 else [0.2, 0.1, 0.05, 0.025]
    errors = [abs(integrate(f, y0, (0.0, 2.0), dt, method).y[-1, 0] - exact(2.0)) for dt in dts]
    assert convergence_order(dts, errors) == pytest.approx(ORDER[method], abs=0.2)


# ---------------------------------------------------------------- one step per scheme

def test_every_method_has_its_step_function():
    assert list(STEPS) == list(METHODS) and list(MECHANICAL_STEPS) == list(MECHANICAL_METHODS)
    assert MECHANICAL_STEPS["explicit_euler"] is mechanical_explicit_euler_step
    assert MECHANICAL_STEPS["semi_implicit_euler"] is mechanical_semi_implicit_euler_step
    for fn in (*STEPS.values(), *MECHANICAL_STEPS.values()):
        assert "eq" in fn.__doc__.lower(), fn.__name__  # each cites the equation it implements


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("problem", ["oscillator", "riccati"])
def test_step_function_is_one_step_of_integrate(method, problem):
    f, y0 = {"oscillator": (oscillator, [1.0, 0.0]), "riccati": (riccati, [1.0])}[problem]
    t0, h = 0.5, 0.25  # binary fractions: integrate's step t1 - t0 is exactly h
    r = integrate(f, y0, (t0, t0 + h), h, method, tol=1e-12)
    history = [] if method in ("implicit_euler", "trapezoidal") else None
    kw = {} if history is None else {"tol": 1e-12, "history": history}
    y1 = STEPS[method](f, t0, np.array(y0), h, **kw)
    np.testing.assert_array_equal(y1, r.y[-1])  # the very same arithmetic
    if history is not None:
        assert history == r.newton


@pytest.mark.parametrize("method", METHODS)
def test_step_function_order_on_decay(method):
    """y' = -y, y(0) = 1 marched to t = 1 by hand with the step function: the error at
    e^-1 falls like dt^order."""
    f = lambda t, y: -y
    dts = [0.1, 0.05, 0.025, 0.0125] if ORDER[method] < 4 else [0.2, 0.1, 0.05, 0.025]
    errors = []
    for dt in dts:
        y = np.array([1.0])
        for k in range(round(1.0 / dt)):
            y = STEPS[method](f, k * dt, y, dt)
        errors.append(abs(y[0] - np.exp(-1.0)))
    assert convergence_order(dts, errors) == pytest.approx(ORDER[method], abs=0.2)


def _mechanical_step(method, system, x, v, t, dt, history=None):
    """One step of ``method`` by its step function, with what simulate precomputes."""
    n, d = x.shape
    if method != "implicit_euler":
        inv_m = np.zeros(n)
        free = np.setdiff1d(np.arange(n), system.fixed)
        inv_m[free] = 1.0 / system.mass[free]
        return MECHANICAL_STEPS[method](system.force, inv_m, x, v, t, dt)
    pinned = (np.asarray(system.fixed, int)[:, None] * d + np.arange(d)).reshape(-1)
    return mechanical_implicit_euler_step(system, system.force, x, v, t, dt,
                                          np.repeat(system.mass, d), pinned, history=history)


@pytest.mark.parametrize("method", MECHANICAL_METHODS)
def test_mechanical_step_function_is_one_step_of_simulate(method):
    c = springs.chain(6, k=400.0, damping=0.1, spring_damping=0.2)
    x0, v0 = c.rest_state()
    x0[1:] += (0.05, -0.1)
    v0[1:] += 0.3
    r = simulate(c, x0, v0, 0.01, 1, method)
    history = []
    x1, v1 = _mechanical_step(method, c, x0, v0, 0.0, 0.01, history)
    x1[c.fixed], v1[c.fixed] = x0[c.fixed], 0.0  # simulate pins after the step
    np.testing.assert_array_equal(x1, r.x[-1])
    np.testing.assert_array_equal(v1, r.v[-1])
    if method == "implicit_euler":
        assert history == r.newton


class _UnitOscillator:
    """x'' = -x for one particle in 1-D (m = 1 kg, k = 1 N/m): exact x = cos t."""
    mass = np.array([1.0])
    fixed = np.array([], int)

    def force(self, x, v, t):
        return -x

    def force_jacobians(self, x, v, t):
        return sp.csr_matrix(-np.eye(1)), sp.csr_matrix((1, 1))


@pytest.mark.parametrize("method", MECHANICAL_METHODS)
def test_mechanical_step_functions_are_first_order(method):
    s = _UnitOscillator()
    dts = [0.02, 0.01, 0.005, 0.0025]
    errors = []
    for dt in dts:
        x, v = np.array([[1.0]]), np.array([[0.0]])
        for k in range(round(1.0 / dt)):
            x, v = _mechanical_step(method, s, x, v, k * dt, dt)
        errors.append(abs(x[0, 0] - np.cos(1.0)))
    assert convergence_order(dts, errors) == pytest.approx(1.0, abs=0.2)


def test_explicit_euler_is_slides_eq3_by_hand():
    r = integrate(oscillator, [1.0, 0.0], (0.0, 0.3), 0.1, "explicit_euler")
    y = np.array([1.0, 0.0])
    for _ in range(3):
        y = y + 0.1 * oscillator(0, y)
    np.testing.assert_allclose(r.y[-1], y, rtol=0, atol=1e-15)
    np.testing.assert_allclose(r.t, [0.0, 0.1, 0.2, 0.3])


def test_last_step_is_shortened_to_end_at_t1():
    r = integrate(lambda t, y: y, [1.0], (0.0, 1.0), 0.3, "explicit_euler")
    np.testing.assert_allclose(r.t, [0.0, 0.3, 0.6, 0.9, 1.0])
    assert r.y[-1, 0] == pytest.approx(1.3**3 * 1.1)  # three full steps, then one of 0.1


@pytest.mark.parametrize("method", METHODS)
def test_stability_function_matches_one_step_on_test_equation(method):
    # y' = λ y with complex λ = a + ib, as a real 2-D system; one step multiplies by R(hλ)
    for lam, h in [(-3.0 + 0.0j, 0.2), (-1.0 + 4.0j, 0.1), (0.5 + 2.0j, 0.3)]:
        A = np.array([[lam.real, -lam.imag], [lam.imag, lam.real]])
        r = integrate(lambda t, y: A @ y, [1.0, 0.0], (0.0, h), h, method,
                      jac=lambda t, y: A, tol=1e-14)
        R = stability_function(method, h * lam)
        np.testing.assert_allclose(r.y[-1], [R.real, R.imag], atol=1e-10)


def test_stiff_problem_implicit_bounded_explicit_diverges():
    # y' = -1000 (y - cos t): |1 + h λ| = 9 at h = 0.01 -> explicit Euler explodes
    f = lambda t, y: -1000.0 * (y - np.cos(t))
    jac = lambda t, y: np.array([[-1000.0]])
    imp = integrate(f, [0.0], (0.0, 5.0), 0.01, "implicit_euler", jac=jac)
    assert np.all(np.abs(imp.y) <= 1.01)
    assert abs(imp.y[-1, 0] - np.cos(5.0)) < 0.01
    with pytest.raises(SimulationDiverged) as info:
        integrate(f, [0.0], (0.0, 5.0), 0.01, "explicit_euler")
    err = info.value
    assert "smaller dt" in str(err) and "implicit" in str(err) and f"step {err.step}" in str(err)
    assert np.all(np.isfinite(err.result.y)) and len(err.result.t) == err.step
    assert np.abs(err.result.y[-1, 0]) > 1e100  # it really grew before overflowing


def test_analytic_dense_sparse_and_fd_jacobians_agree():
    args = (oscillator, [1.0, 0.0], (0.0, 1.0), 0.05)
    a = integrate(*args, "trapezoidal", jac=oscillator_jac).y
    b = integrate(*args, "trapezoidal").y
    c = integrate(*args, "trapezoidal", jac=lambda t, y: sp.csr_matrix(oscillator_jac(t, y))).y
    np.testing.assert_allclose(a, b, atol=1e-9)
    np.testing.assert_allclose(a, c, atol=1e-12)
    # a linear problem with its exact Jacobian: Newton lands in one iteration every step
    r = integrate(*args, "implicit_euler", jac=oscillator_jac, tol=1e-12)
    assert all(len(h) == 2 for h in r.newton)
    wrong = integrate(*args, "implicit_euler", jac=lambda t, y: -3 * oscillator_jac(t, y), tol=1e-12)
    assert max(len(h) for h in wrong.newton) > 2
    np.testing.assert_allclose(finite_difference_jacobian(oscillator, 0.0, np.array([0.3, 2.0])),
                               oscillator_jac(0, 0), atol=1e-9)


def worked_example_first_order(k=50.0, m=1.0, gamma=0.5, L=1.0, g=9.81, anchor=(0.0, 0.0)):
    """Slides 'An example': y = (x, v) in 2-D, f from eq. (9) with the three forces."""
    xb = np.asarray(anchor)

    def f(t, y):
        x, v = y[:2], y[2:]
        d = x - xb
        F = -gamma * v - k * (np.linalg.norm(d) - L) * d / np.linalg.norm(d) - m * np.array([0, g])
        return np.concatenate([v, F / m])

    return f


def test_newton_converges_quadratically_on_worked_example():
    f = worked_example_first_order()
    y0 = np.array([0.3, -1.8, 2.0, 0.0])  # a far-from-equilibrium state so Newton needs a few iterations
    r = integrate(f, y0, (0.0, 0.2), 0.2, "implicit_euler", tol=1e-14)
    res = np.array(r.newton[0])
    assert len(res) >= 4 and res[-1] < 1e-12
    # quadratic: r_{k+1} <= C r_k^2 with a moderate C, once in the basin
    resolved = res[1:] > 1e-13  # pairs whose new residual is above round-off
    ratios = res[1:][resolved] / res[:-1][resolved] ** 2
    assert len(ratios) >= 3 and np.all(ratios[1:] < 1.0), ratios
    # and the number of correct digits roughly doubles on the last fully resolved step
    assert np.log(res[-2]) / np.log(res[-3]) > 1.7


def test_newton_without_line_search_and_failure_reports_history():
    G = lambda z: np.arctan(z)
    J = lambda z: np.diag(1 / (1 + z**2))
    # plain Newton diverges on arctan from |z0| > 1.39; the line search rescues it
    assert newton_solve(G, J, np.array([3.0])).converged
    with pytest.raises(ConvergenceError) as info:
        newton_solve(G, J, np.array([3.0]), line_search=False, max_iter=8)
    assert len(info.value.residuals) >= 2 and info.value.residuals[-1] > info.value.residuals[0]


def test_newton_failure_inside_integrate_names_the_step():
    f = lambda t, y: np.array([-y[0] ** 3 + np.exp(y[0])])
    with pytest.raises(ConvergenceError, match=r"implicit_euler step 1 \(t = 0\)") as info:
        integrate(f, [3.0], (0.0, 1.0), 0.5, "implicit_euler", max_iter=1)
    assert len(info.value.residuals) == 2


def test_bad_inputs_raise_clear_errors():
    with pytest.raises(ValueError, match="dt must be"):
        integrate(oscillator, [1, 0], (0, 1), 0.0)
    with pytest.raises(ValueError, match="dt must be"):
        integrate(oscillator, [1, 0], (0, 1), -0.1)
    with pytest.raises(ValueError, match="NaN"):
        integrate(oscillator, [np.nan, 0], (0, 1), 0.1)
    with pytest.raises(ValueError, match="valid methods are: explicit_euler, midpoint"):
        integrate(oscillator, [1, 0], (0, 1), 0.1, "euler")
    with pytest.raises(ValueError, match="1-D"):
        integrate(oscillator, np.zeros((2, 2)), (0, 1), 0.1)
    with pytest.raises(ValueError, match="shape"):
        integrate(lambda t, y: np.zeros(3), [1, 0], (0, 1), 0.1)
    with pytest.raises(ValueError, match="t0 < t1"):
        integrate(oscillator, [1, 0], (1, 0), 0.1)
    s = springs.hanging_spring()
    x0, v0 = s.rest_state()
    with pytest.raises(ValueError, match="dt must be"):
        simulate(s, x0, v0, 0.0, 10)
    with pytest.raises(ValueError, match="semi_implicit_euler"):
        simulate(s, x0, v0, 0.01, 10, "rk4")
    with pytest.raises(ValueError, match="shape"):
        simulate(s, x0[:1], v0, 0.01, 10)
    with pytest.raises(ValueError, match="NaN"):
        simulate(s, x0, v0 * np.nan, 0.01, 10)
    with pytest.raises(ValueError, match="n_steps"):
        simulate(s, x0, v0, 0.01, -1)
    with pytest.raises(ValueError, match="valid solvers"):
        LinearSolver("magic")


def test_mechanical_blow_up_names_step_and_suggests_fix():
    s = springs.hanging_spring(k=1e6, m=1.0)
    x0, v0 = s.rest_state()
    x0[1, 1] -= 0.1
    with pytest.raises(SimulationDiverged, match="implicit method") as info:
        simulate(s, x0, v0, 0.01, 2000, "explicit_euler")
    assert info.value.result.x.shape[0] == info.value.step
    imp = simulate(s, x0, v0, 0.01, 2000, "implicit_euler")
    assert np.abs(imp.x).max() < 2.0


@pytest.mark.parametrize("method", ["explicit_euler", "semi_implicit_euler", "implicit_euler"])
def test_pinned_particles_never_move(method):
    c = springs.cloth_grid(6, 5, k=500.0)
    x0, v0 = c.rest_state()
    v0 += 0.3
    # 100 steps: explicit Euler is unstable on this cloth and blows up (detected) after ~120
    r = simulate(c, x0, v0, 0.002, 100, method)
    assert np.all(r.x[:, c.fixed] == x0[c.fixed])
    assert np.all(r.v[:, c.fixed] == 0.0)
    free = np.setdiff1d(np.arange(c.n), c.fixed)
    assert np.abs(r.x[-1, free] - x0[free]).max() > 1e-3  # the rest did move


def test_semi_implicit_is_pa_eq7_and_explicit_is_slides_eq4_by_hand():
    s = springs.hanging_spring(k=30.0, m=2.0, damping=0.3)
    x, v = s.rest_state()
    x[1] += (0.2, -0.1)
    r_si = simulate(s, x, v, 0.01, 1, "semi_implicit_euler")
    r_ex = simulate(s, x, v, 0.01, 1, "explicit_euler")
    a = s.force(x, v) / s.mass[:, None]
    v_new = v + 0.01 * a
    np.testing.assert_allclose(r_si.x[1, 1], x[1] + 0.01 * v_new[1])
    np.testing.assert_allclose(r_ex.x[1, 1], x[1] + 0.01 * v[1])
    np.testing.assert_allclose(r_ex.v[1, 1], v_new[1])


def test_mechanical_implicit_euler_equals_first_order_implicit_euler():
    """simulate(implicit_euler) solves slides eq. (12) for y = (x, v): compare with integrate."""
    s = springs.hanging_spring(k=50.0, m=1.0, damping=0.5)
    x0, v0 = s.rest_state()
    x0[1] = (0.3, -1.8)
    v0[1] = (2.0, 0.0)
    mech = simulate(s, x0, v0, 0.05, 20, "implicit_euler", tol=1e-13)
    f = worked_example_first_order(k=50.0, m=1.0, gamma=0.5)
    first = integrate(f, np.concatenate([x0[1], v0[1]]), (0.0, 1.0), 0.05, "implicit_euler", tol=1e-13)
    np.testing.assert_allclose(mech.x[:, 1], first.y[:, :2], atol=1e-9)
    np.testing.assert_allclose(mech.v[:, 1], first.y[:, 2:], atol=1e-9)
    # and Newton converged quadratically there too
    hist = np.array(mech.newton[0])
    assert hist[-1] < 1e-12
    resolved = hist[1:] > 1e-13
    assert np.all(hist[1:][resolved] <= 10 * hist[:-1][resolved] ** 2)


def test_baraff_witkin_is_one_linearised_step_close_to_full_newton():
    c = springs.chain(8, k=2000.0, damping=0.1)
    x0, v0 = c.rest_state()
    bw = simulate(c, x0, v0, 0.01, 50, "implicit_euler", newton="baraff_witkin")
    full = simulate(c, x0, v0, 0.01, 50, "implicit_euler", newton="full", tol=1e-12, atol=1e-14)
    assert all(len(h) == 2 for h in bw.newton)
    assert all(h[-1] <= max(1e-12 * h[0], 1e-14) for h in full.newton)
    diff = np.abs(bw.x - full.x).max()
    assert 0 < diff < 0.05


@pytest.mark.parametrize("kind", ["direct", "cg", "lagged"])
def test_linear_solver_kinds_agree(kind):
    c = springs.cloth_grid(12, 10, k=800.0, damping=0.05)
    x0, v0 = c.rest_state()
    ref = simulate(c, x0, v0, 1 / 60, 15, "implicit_euler", solver="direct", tol=1e-12)
    ls = LinearSolver(kind, rtol=1e-12)
    got = simulate(c, x0, v0, 1 / 60, 15, "implicit_euler", solver=ls, tol=1e-12)
    np.testing.assert_allclose(got.x, ref.x, atol=1e-8)
    if kind == "lagged":
        assert ls.stats["factorizations"] < ls.stats["solves"]  # the factorisation was reused


def test_energy_behaviour_of_the_three_mechanical_methods():
    c = springs.chain(10, k=300.0, total_mass=1.0, damping=0.0)
    x0, v0 = c.rest_state()
    E0 = c.energy(x0, v0)
    E = {m: np.array([c.energy(x, v) for x, v in zip(r.x, r.v)])
         for m, n in (("explicit_euler", 400), ("semi_implicit_euler", 5000))
         for r in [simulate(c, x0, v0, 0.002, n, m)]}
    swing = E0 - c.potential_energy(c.X + (0, -0.5))  # scale of the energy exchanged
    assert np.abs(E["semi_implicit_euler"] - E0).max() < 0.05 * abs(swing)  # bounded band
    assert E["explicit_euler"][-1] - E0 > 0.5 * abs(swing)  # explicit Euler gains energy
    with pytest.raises(SimulationDiverged, match=r"step \d+ .*moved .* from its start"):
        simulate(c, x0, v0, 0.002, 5000, "explicit_euler")    # ... until it blows up
    damped = springs.chain(10, k=300.0, total_mass=1.0, damping=0.2, spring_damping=0.5)
    r = simulate(damped, x0, v0, 0.01, 600, "implicit_euler")
    Ed = np.array([damped.energy(x, v) for x, v in zip(r.x, r.v)])
    assert np.all(np.diff(Ed) <= 1e-9 * np.abs(Ed).max())


def test_hanging_spring_settles_at_static_equilibrium():
    k, m, L, g = 80.0, 1.5, 1.0, 9.81
    s = springs.hanging_spring(anchor=(0.5, 2.0), L=L, k=k, m=m, damping=3.0, g=g)
    x0, v0 = s.rest_state()
    for method in ("semi_implicit_euler", "implicit_euler"):
        r = simulate(s, x0, v0, 0.01, 3000, method)
        np.testing.assert_allclose(r.x[-1, 1], (0.5, 2.0 - (L + m * g / k)), atol=1e-6)


def test_convergence_order_helper():
    dts = np.array([0.1, 0.05, 0.025])
    assert convergence_order(dts, 3 * dts**2) == pytest.approx(2.0)
    with pytest.raises(ValueError):
        convergence_order([0.1], [0.2])


def test_save_every_subsamples_and_project_hook_constrains():
    c = springs.chain(6, k=400.0)
    x0, v0 = c.rest_state()
    full = simulate(c, x0, v0, 0.002, 300, "semi_implicit_euler")
    sub = simulate(c, x0, v0, 0.002, 300, "semi_implicit_euler", save_every=50)
    np.testing.assert_allclose(sub.x, full.x[::50])
    np.testing.assert_allclose(sub.t, full.t[::50])
    calls = []

    def floor(t, x, v):  # a ground at y = -0.3: project and stop
        calls.append(t)
        below = x[:, 1] < -0.3
        x[below, 1] = -0.3
        v[below, 1] = 0.0

    r = simulate(c, x0, v0, 0.002, 300, "semi_implicit_euler", project=floor)
    assert r.x[:, :, 1].min() >= -0.3 and full.x[:, :, 1].min() < -0.3
    assert calls[0] == pytest.approx(0.002) and len(calls) == 300



def test_lagged_solver_with_metis_and_non_symmetric_matrix():
    """> 2,000 unknowns (METIS ordering) and spring damping (non-symmetric A: CG may fail
    and must fall back to a fresh factorisation without a wrong answer)."""
    c = springs.cloth_grid(35, 30, k=800.0, damping=0.01, spring_damping=0.5)
    x0, v0 = c.rest_state()
    ref = simulate(c, x0, v0, 1 / 60, 4, "implicit_euler", solver="direct", tol=1e-10, atol=1e-14)
    ls = LinearSolver("lagged")
    got = simulate(c, x0, v0, 1 / 60, 4, "implicit_euler", solver=ls, tol=1e-10, atol=1e-14)
    assert c.n * c.d > 2000 and ls._perm is not None and ls._perm[2] is not None
    np.testing.assert_allclose(got.x, ref.x, atol=1e-7)


class _PinnedMassless:
    """Particle 0 pinned and massless; no springs at all (empty K, D patterns)."""
    mass = np.array([0.0, 1.0])
    fixed = [0]

    def force(self, x, v, t):
        return np.array([[0.0, 0.0], [0.0, -9.81]])

    def force_jacobians(self, x, v, t):
        import scipy.sparse as sp
        return sp.csr_matrix((4, 4)), sp.csr_matrix((4, 4))


def test_massless_pinned_particle_with_empty_jacobians():
    r = simulate(_PinnedMassless(), np.zeros((2, 2)), np.zeros((2, 2)), 0.1, 3, "implicit_euler")
    np.testing.assert_allclose(r.v[-1, 1], [0.0, -3 * 0.981])
    assert np.all(r.x[:, 0] == 0)


class _WrongJacobian:
    mass = np.array([1.0])
    fixed = []

    def force(self, x, v, t):
        return np.array([[0.0, -1e4 * x[0, 1] ** 3]])

    def force_jacobians(self, x, v, t):  # wrong sign: Newton directions are not descent
        import scipy.sparse as sp
        return sp.csr_matrix(np.diag([0.0, +3e4 * x[0, 1] ** 2])), sp.csr_matrix((2, 2))


def test_failed_line_search_raises_instead_of_passing_silently():
    with pytest.raises(ConvergenceError):
        simulate(_WrongJacobian(), np.array([[0.0, 1.0]]), np.array([[1e5, -20.0]]), 0.01, 1,
                 "implicit_euler")
