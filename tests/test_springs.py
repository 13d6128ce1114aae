"""physlab.springs: Hooke's law, energy gradients, Jacobians, builders and input checks."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from physlab import springs
from physlab.integrators import SimulationDiverged, simulate
from physlab.springs import SpringSystem


def fd_gradient(fun, x, eps=1e-6):
    g = np.zeros_like(x)
    for idx in np.ndindex(x.shape):
        e = np.zeros_like(x)
        e[idx] = eps
        g[idx] = (fun(x + e) - fun(x - e)) / (2 * eps)
    return g


def fd_jacobian(fun, x, eps=1e-6):
    cols = []
    for idx in np.ndindex(x.shape):
        e = np.zeros_like(x)
        e[idx] = eps
        cols.append(((fun(x + e) - fun(x - e)) / (2 * eps)).reshape(-1))
    return np.array(cols).T


def random_system(rng, n=7, d=2, ground=None, spring_damping=0.0):
    X = rng.normal(size=(n, d))
    edges = np.array([(i, j) for i in range(n) for j in range(i + 1, n) if rng.random() < 0.5] + [(0, 1)])
    return SpringSystem(X, edges, k=rng.uniform(10, 100, len(edges)), mass=rng.uniform(0.5, 2, n),
                        damping=0.3, fixed=[0], spring_damping=spring_damping, ground=ground)


def test_single_spring_hooke_analytic():
    s = SpringSystem([[0.0, 0.0], [2.0, 0.0]], [[0, 1]], k=10.0, rest_length=1.5, gravity=(0, 0))
    f = s.force(s.X, np.zeros((2, 2)))
    np.testing.assert_allclose(f, [[5.0, 0.0], [-5.0, 0.0]])  # stretched by 0.5: pulls ends together
    fc = s.force(np.array([[0.0, 0.0], [0.0, 1.0]]), np.zeros((2, 2)))
    np.testing.assert_allclose(fc, [[0.0, -5.0], [0.0, 5.0]])  # compressed by 0.5: pushes apart


@pytest.mark.parametrize("d", [2, 3])
def test_forces_are_minus_energy_gradient(d):
    rng = np.random.default_rng(d)
    s = random_system(rng, d=d, ground=-0.2)
    x = s.X + 0.2 * rng.normal(size=s.X.shape)
    x[2, 1] = -0.5  # below the ground: the penalty is active
    v = np.zeros_like(x)
    s.damping = 0.0
    f = s.force(x, v)
    np.testing.assert_allclose(f, -fd_gradient(s.potential_energy, x), rtol=1e-6, atol=1e-8 * np.abs(f).max())


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), d=st.sampled_from([2, 3]))
def test_jacobians_match_finite_differences(seed, d):
    rng = np.random.default_rng(seed)
    s = random_system(rng, n=6, d=d, ground=0.0, spring_damping=rng.uniform(0, 2))
    x = s.X + 0.1 * rng.normal(size=s.X.shape)
    v = rng.normal(size=x.shape)
    K, D = s.force_jacobians(x, v)
    np.testing.assert_allclose(K.toarray(), fd_jacobian(lambda y: s.force(y, v), x), rtol=1e-5, atol=1e-4)
    np.testing.assert_allclose(D.toarray(), fd_jacobian(lambda w: s.force(x, w), v), rtol=1e-5, atol=1e-5)


def test_internal_forces_cancel_and_have_no_torque():
    rng = np.random.default_rng(1)
    s = random_system(rng)
    x = s.X + 0.3 * rng.normal(size=s.X.shape)
    fe = s.spring_forces(x)
    f = np.zeros_like(x)
    np.add.at(f, s.edges[:, 0], fe)
    np.add.at(f, s.edges[:, 1], -fe)
    np.testing.assert_allclose(f.sum(0), 0, atol=1e-10)
    torque = np.sum(x[:, 0] * f[:, 1] - x[:, 1] * f[:, 0])
    assert abs(torque) < 1e-10
    total = s.force(x, np.zeros_like(x))  # undamped, still: only gravity remains in the sum
    np.testing.assert_allclose(total.sum(0), s.mass.sum() * s.gravity, atol=1e-10)


def test_stiffness_matrix_symmetric_and_kills_rigid_translation():
    c = springs.cloth_grid(5, 4, k=100.0)
    x = c.X * 1.1
    K, D = c.force_jacobians(x, np.zeros_like(x))
    assert abs(K - K.T).max() < 1e-12
    t = np.tile([0.3, -0.7], c.n)
    np.testing.assert_allclose(K @ t, 0, atol=1e-10)
    np.testing.assert_allclose(D.diagonal(), -c.damping)
    assert np.array_equal(K.indptr, D.indptr) and np.array_equal(K.indices, D.indices)


def test_repeated_springs_add_up():
    X = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]
    once = SpringSystem(X, [[0, 1], [1, 2]], k=[20.0, 5.0])
    twice = SpringSystem(X, [[0, 1], [0, 1], [1, 2]], k=[10.0, 10.0, 5.0])
    x = np.array(X) * 1.3
    v = np.zeros_like(x)
    np.testing.assert_allclose(once.force(x, v), twice.force(x, v))
    np.testing.assert_allclose(once.force_jacobians(x, v)[0].toarray(), twice.force_jacobians(x, v)[0].toarray())


def test_energy_components():
    s = springs.hanging_spring(anchor=(0, 0), L=1.0, k=10.0, m=2.0)
    x, v = s.rest_state()
    x[1] = (0.0, -1.5)
    v[1] = (3.0, 0.0)
    expected = 0.5 * 2.0 * 9.0 + 0.5 * 10.0 * 0.25 + 2.0 * 9.81 * (-1.5)
    assert s.energy(x, v) == pytest.approx(expected)


def test_builders():
    e, kind = springs.grid_edges(4, 3)
    assert (kind == "structural").sum() == 3 * 3 + 4 * 2
    assert (kind == "shear").sum() == 2 * 3 * 2
    assert (kind == "bend").sum() == 3 * 2 + 4 * 1
    c = springs.cloth_grid(4, 3)
    assert list(c.fixed) == [0, 3] and c.mass.sum() == pytest.approx(1.0)
    c3 = springs.cloth_grid(4, 3, dim=3)
    assert c3.d == 3 and np.allclose(c3.X[:, 1], 0) and np.allclose(c3.gravity, (0, -9.81, 0))
    ch = springs.chain(5, length=2.0, pin="both")
    assert list(ch.fixed) == [0, 4] and np.allclose(ch.rest_length, 0.5)
    hs = springs.hanging_spring(anchor=(1.0, 2.0), L=0.5)
    np.testing.assert_allclose(hs.X, [[1.0, 2.0], [1.0, 1.5]])  # y0 = (x̄0 + (0, -L), 0)
    box = springs.soft_box(drop_height=0.5)
    assert box.ground == 0.0 and box.X[:, 1].min() > 0.4
    with pytest.raises(ValueError, match="pin"):
        springs.chain(5, pin="middle")


def test_critical_time_step_of_single_spring():
    s = springs.hanging_spring(k=40.0)  # one free particle of 1 kg: ω = sqrt(k/m)
    assert springs.critical_time_step(s) == pytest.approx(2 / np.sqrt(40.0))


def _run(system, dt, duration, method):
    """``(result, blew_up_step or None)`` of a run from rest (a blow-up ends it)."""
    x0, v0 = system.rest_state()
    try:
        return simulate(system, x0, v0, dt, max(1, int(round(duration / dt))), method), None
    except SimulationDiverged as err:
        return err.result, err.step


def test_critical_time_step_predicts_semi_implicit_blow_up():
    s = springs.chain(12, length=1.0, k=600.0, total_mass=1.0)  # lesson 03's chain
    dc = springs.critical_time_step(s)
    _, blew_below = _run(s, 0.9 * dc, 10.0, "semi_implicit_euler")
    _, blew_above = _run(s, 1.2 * dc, 10.0, "semi_implicit_euler")
    assert blew_below is None and blew_above is not None
    assert dc == pytest.approx(0.01189591218784041, rel=1e-9)  # reference number


def test_bad_inputs_raise_clear_errors():
    X = np.zeros((3, 2))
    X[:, 0] = [0, 1, 2]
    with pytest.raises(ValueError, match="does not exist"):
        SpringSystem(X, [[0, 3]], k=1.0)
    with pytest.raises(ValueError, match="itself"):
        SpringSystem(X, [[1, 1]], k=1.0)
    with pytest.raises(ValueError, match="negative mass"):
        SpringSystem(X, [[0, 1]], k=1.0, mass=[1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match="mass > 0"):
        SpringSystem(X, [[0, 1]], k=1.0, mass=[0.0, 1.0, 1.0])
    SpringSystem(X, [[0, 1]], k=1.0, mass=[0.0, 1.0, 1.0], fixed=[0])  # pinned may be massless
    with pytest.raises(ValueError, match="one per edge"):
        SpringSystem(X, [[0, 1]], k=[1.0, 2.0])
    with pytest.raises(ValueError, match=r"\(E, 2\)"):
        SpringSystem(X, [0, 1], k=1.0)
    with pytest.raises(ValueError, match="gravity"):
        SpringSystem(X, [[0, 1]], k=1.0, gravity=(0, 0, -9.81))
    with pytest.raises(ValueError, match="NaN"):
        SpringSystem(X * np.nan, [[0, 1]], k=1.0)
    with pytest.raises(ValueError, match="damping"):
        SpringSystem(X, [[0, 1]], k=1.0, damping=-1.0)
    s = SpringSystem(X, [[0, 1]], k=1.0)
    with pytest.raises(ValueError, match="shape"):
        s.force(np.zeros((2, 2)), np.zeros((2, 2)))
    with pytest.raises(TypeError, match="system must be a physlab.springs.SpringSystem"):
        springs.critical_time_step(None)
