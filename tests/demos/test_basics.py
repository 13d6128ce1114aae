"""physlab.demos.basics: the lesson callbacks and the worked example's exact solution."""
import numpy as np
import pytest
from matplotlib.figure import Figure

from physlab.demos import basics
from physlab.integrators import METHODS, ORDER, integrate


def test_hanging_spring_exact_solution_solves_the_ode():
    p = basics.HangingSpring(k=40.0, m=1.5, gamma=0.7)
    t = np.linspace(0, 3, 301)
    y = p.exact(t)
    np.testing.assert_allclose(y[0], p.y0, atol=1e-14)
    # exact derivative vs f(t, y): central differences of the closed form
    h = 1e-6
    dy = (p.exact(t + h) - p.exact(t - h)) / (2 * h)
    f = np.array([p.f(ti, yi) for ti, yi in zip(t, y)])
    np.testing.assert_allclose(dy, f, atol=1e-6)
    # ... and a tight RK4 run agrees
    r = integrate(p.f, p.y0, (0.0, 3.0), 1e-3, "rk4")
    np.testing.assert_allclose(r.y[-1], y[-1], atol=1e-9)
    np.testing.assert_allclose(p.jac(0, y[5]), _fd_jac(p.f, y[5]), atol=1e-6)


def _fd_jac(f, y, h=1e-6):
    return np.array([(f(0, y + h * e) - f(0, y - h * e)) / (2 * h) for e in np.eye(len(y))]).T


@pytest.mark.parametrize("gamma", [0.0, 3.0, 2 * np.sqrt(40.0 * 1.5), 40.0])  # under/critical/over
def test_exact_solution_all_damping_regimes(gamma):
    p = basics.HangingSpring(k=40.0, m=1.5, gamma=gamma)
    r = integrate(p.f, p.y0, (0.0, 2.0), 1e-3, "rk4")
    np.testing.assert_allclose(r.y[::100], p.exact(r.t[::100]), atol=1e-9)


def test_hanging_spring_matches_spring_system():
    p = basics.HangingSpring(k=30.0, m=2.0, gamma=0.4)
    s = p.system()
    x = np.array([[0.0, 0.0], [0.2, -1.3]])
    v = np.array([[0.0, 0.0], [0.5, -0.1]])
    np.testing.assert_allclose(s.force(x, v)[1], p.forces(x[1], v[1]))
    np.testing.assert_allclose(p.equilibrium, (0.0, -1.0 - 2.0 * 9.81 / 30.0))


def test_convergence_study_orders():
    errors = basics.convergence_study(dts=(0.01, 0.005, 0.0025, 0.00125))
    from physlab.integrators import convergence_order

    for m in METHODS:
        assert convergence_order((0.01, 0.005, 0.0025, 0.00125), errors[m]) == pytest.approx(ORDER[m], abs=0.2)


@pytest.mark.parametrize("call", [
    lambda: basics.ode_demo(),
    lambda: basics.ode_demo(dt=0.4, method="explicit_euler"),  # blows up: still a figure
    lambda: basics.ode_demo(dt=0.05, method="trapezoidal", gamma=1.0),
    lambda: basics.stiff_spring_demo(),
    lambda: basics.stability_demo(dt=0.3),
    lambda: basics.newton_demo()[0],
    lambda: basics.convergence_demo(methods=("heun",))[0],
    lambda: basics.mass_spring_demo("hanging"),
    lambda: basics.mass_spring_demo("soft_box", dt=0.005),  # explicit methods blow up here
    lambda: basics.mass_spring_demo("cloth", method="implicit_euler", dt=0.02, duration=0.5),
])
def test_callbacks_return_drawable_figures(call, tmp_path):
    fig = call()
    assert isinstance(fig, Figure)
    path = tmp_path / "fig.png"
    fig.savefig(path)
    assert path.stat().st_size > 5_000
    # every axes shows something
    for ax in fig.axes:
        if ax.get_label() != "<colorbar>":
            assert ax.lines or ax.collections or ax.images


def test_ode_demo_reports_blow_up_in_title():
    fig = basics.ode_demo(dt=0.45, method="explicit_euler", t_end=200.0)
    assert "blew up" in fig._suptitle.get_text()


def test_newton_demo_residuals_fall_quadratically():
    _, res = basics.newton_demo(dt=0.2, y0=[0.3, -1.8, 2.0, 0.0])
    res = np.asarray(res)
    assert res[-1] < 1e-12 * res[0]
    assert len(res) <= 8


def test_critical_time_step_of_single_spring():
    s = basics.make_scene("hanging", k=40.0)  # one free particle of 1 kg: ω = sqrt(k/m)
    assert basics.critical_time_step(s) == pytest.approx(2 / np.sqrt(40.0))


def test_critical_time_step_predicts_semi_implicit_blow_up():
    s = basics.make_scene("chain")
    dc = basics.critical_time_step(s)
    _, blew_below = basics.run_scene(s, 0.9 * dc, 10.0, "semi_implicit_euler")
    _, blew_above = basics.run_scene(s, 1.2 * dc, 10.0, "semi_implicit_euler")
    assert blew_below is None and blew_above is not None


def test_make_scene_validates():
    with pytest.raises(ValueError, match="valid scenes are"):
        basics.make_scene("trampoline")
    assert basics.make_scene("cloth", k=100.0).k.max() == 100.0
