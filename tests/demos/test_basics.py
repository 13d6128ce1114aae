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


def test_critical_time_step_is_re_exported_for_lesson_03():
    """The function lives in physlab.springs (tests/test_springs.py); lesson 03 imports it
    from here."""
    from physlab import springs

    assert basics.critical_time_step is springs.critical_time_step


def test_make_scene_validates():
    with pytest.raises(ValueError, match="valid scenes are"):
        basics.make_scene("trampoline")
    assert basics.make_scene("cloth", k=100.0).k.max() == 100.0


# ---------------------------------------------------------------- bad inputs name the culprit

@pytest.mark.parametrize("call, error, match", [
    (lambda: basics.HangingSpring(k=0.0), ValueError, r"HangingSpring\.k must be > 0"),
    (lambda: basics.HangingSpring(m=float("nan")), ValueError, r"HangingSpring\.m must be finite"),
    (lambda: basics.HangingSpring(gamma=-1.0), ValueError, r"HangingSpring\.gamma must be >= 0"),
    (lambda: basics.HangingSpring(anchor=(0.0,)), ValueError, r"HangingSpring\.anchor must have 2"),
    (lambda: basics.ode_demo(t_end=0.0), ValueError, r"t_end \(s\) must be > 0"),
    (lambda: basics.ode_demo(k=-40.0), ValueError, r"HangingSpring\.k must be > 0"),
    (lambda: basics.ode_demo(method="euler"), ValueError, "unknown method .euler.; valid values are: explicit_euler"),
    (lambda: basics.convergence_study(dts=(0.01,)), ValueError, "at least two different time steps"),
    (lambda: basics.convergence_study(dts=(0.01, -0.005)), ValueError, r"each of dts \(s\) must be > 0"),
    (lambda: basics.convergence_study(dts=0.01), TypeError, "dts must be a sequence"),
    (lambda: basics.newton_demo(y0=[0.0, -1.0]), ValueError, "y0 must be 4 finite numbers"),
    (lambda: basics.stiff_spring_demo(t_end=-1.0), ValueError, r"t_end \(s\) must be > 0"),
    (lambda: basics.stability_demo(dt=0.0), ValueError, r"dt \(s\) must be > 0"),
    (lambda: basics.stability_demo(m=0.0), ValueError, r"HangingSpring\.m must be > 0"),
    (lambda: basics.make_scene("chain", k=0.0), ValueError, r"k \(N/m\) must be > 0"),
    (lambda: basics.make_scene("chain", k="stiff"), TypeError, r"k \(N/m\) must be a number"),
    (lambda: basics.make_scene("chain", damping=-0.1), ValueError, r"damping γ \(N·s/m\) must be >= 0"),
    (lambda: basics.make_scene(None), ValueError, "valid scenes are"),
    (lambda: basics.run_scene("chain"), TypeError, "system must be a physlab.springs.SpringSystem"),
    (lambda: basics.run_scene(basics.make_scene(), dt=0.0), ValueError, r"dt \(s\) must be > 0"),
    (lambda: basics.run_scene(basics.make_scene(), duration=float("inf")), ValueError,
     r"duration \(s\) must be finite"),
    (lambda: basics.run_scene(basics.make_scene(), method="rk4"), ValueError, "unknown method 'rk4'"),
    (lambda: basics.run_scene(basics.make_scene(), newton="quasi"), ValueError, "unknown newton 'quasi'"),
    (lambda: basics.energy_comparison(basics.make_scene(), methods=("heun",)), ValueError,
     "unknown method 'heun'"),
    (lambda: basics.mass_spring_demo(dt=-0.004), ValueError, r"dt \(s\) must be > 0"),
    (lambda: basics.mass_spring_demo(dt=float("nan")), ValueError, r"dt \(s\) must be finite"),
    (lambda: basics.mass_spring_demo(duration=0.0), ValueError, r"duration \(s\) must be > 0"),
    (lambda: basics.mass_spring_demo(method="midpoint"), ValueError, "valid values are: explicit_euler"),
    (lambda: basics.mass_spring_demo(compare="yes"), TypeError, "compare must be True or False"),
    (lambda: basics.mass_spring_demo(max_steps=0), ValueError, "max_steps must be >= 1"),
    (lambda: basics.mass_spring_demo(dt=1e-6, duration=1.0, max_steps=None), ValueError,
     "too many for a widget"),
])
def test_bad_inputs_raise_clear_errors(call, error, match):
    with pytest.raises(error, match=match):
        call()


# ---------------------------------------------------------------- mass_spring_demo (lessons 00, 03)

def _left_panel(fig):
    return fig.axes[0]


def test_mass_spring_demo_redraw_after_moving_the_method_does_not_simulate(monkeypatch):
    basics._scene_run.cache_clear()
    basics._scene_energy.cache_clear()
    calls = []
    real = basics.simulate
    monkeypatch.setattr(basics, "simulate", lambda *a, **k: calls.append(a[5]) or real(*a, **k))
    kw = dict(scene="hanging", dt=0.01, duration=0.3)
    basics.mass_spring_demo(method="semi_implicit_euler", **kw)
    assert sorted(calls) == sorted(basics.MECHANICAL_METHODS)  # the energy panel needs all three
    for m in basics.MECHANICAL_METHODS:  # moving the method dropdown: no new simulation
        basics.mass_spring_demo(method=m, **kw)
    assert len(calls) == 3
    basics.mass_spring_demo(method="implicit_euler", k=41.0, **kw)  # a new k: simulated again
    assert len(calls) == 6


def test_mass_spring_demo_axes_in_metres_and_colours_explained():
    sparse = basics.mass_spring_demo("chain", dt=0.01, duration=0.5)
    dense = basics.mass_spring_demo("cloth", dt=0.01, duration=0.5)
    for fig, bar in ((sparse, "snapshot time t (s)"), (dense, "strain l/L - 1")):
        ax = _left_panel(fig)
        assert (ax.get_xlabel(), ax.get_ylabel()) == ("x (m)", "y (m)")
        cbar = [a for a in fig.axes if a.get_xlabel().startswith(bar)]
        assert len(cbar) == 1, [a.get_xlabel() for a in fig.axes]
        assert fig.axes[1].get_ylabel() == "total energy (J)"
    assert "path of the far corner" in [t.get_text() for t in _left_panel(dense).get_legend().get_texts()]


def test_cloth_scene_swings_away_from_its_rest_grid():
    s = basics.make_scene("cloth")
    r, blew = basics.run_scene(s, dt=0.01, duration=1.5, method="implicit_euler",
                               newton="baraff_witkin")
    assert blew is None
    moved = np.linalg.norm(r.x - s.X, axis=-1)  # (T, n)
    assert moved[-1].mean() > 0.3  # the last frame is far from the rest grid (m)
    # it swings: the far corner's horizontal position passes to the other side of the pin
    far = np.argmax(np.linalg.norm(s.X - s.X[s.fixed[0]], axis=1))
    assert r.x[:, far, 0].min() < s.X[s.fixed[0], 0] - 0.3 < s.X[far, 0]
    fig = basics.mass_spring_demo("cloth", dt=0.01, duration=1.5)
    path = [ln for ln in _left_panel(fig).lines if ln.get_label() == "path of the far corner"][0]
    assert np.ptp(path.get_xdata()) > 0.5


def test_mass_spring_demo_bounds_the_number_of_steps():
    fig = basics.mass_spring_demo("hanging", dt=0.002, duration=3.0, max_steps=50)
    energy = fig.axes[1]
    assert "50 steps" in energy.get_title()
    t_end = max(ln.get_xdata()[-1] for ln in energy.lines if len(ln.get_xdata()) > 2)
    assert t_end == pytest.approx(0.1)


def test_baraff_witkin_widget_run_matches_full_newton_and_never_gains_energy():
    s = basics.make_scene("chain")
    full, _ = basics.run_scene(s, 0.004, 1.0, "implicit_euler", newton="full")
    bw, _ = basics.run_scene(s, 0.004, 1.0, "implicit_euler", newton="baraff_witkin")
    E = basics.energy_comparison(s, 0.004, 1.0, ("implicit_euler",), runs={"implicit_euler": (bw, None)})
    e = E["implicit_euler"][1]
    assert np.all(np.diff(e) < 1e-9)
    assert np.abs(full.x - bw.x).max() < 0.05  # m, over 250 steps of a falling rope


def test_dense_solver_gives_the_sparse_solution():
    from physlab.integrators import simulate

    s = basics.make_scene("soft_box")  # 72 unknowns: above the library's dense limit
    x0, v0 = s.rest_state()
    ref = simulate(s, x0, v0, 0.01, 30, "implicit_euler", solver="direct")
    r, blew = basics.run_scene(s, 0.01, 0.3, "implicit_euler")
    assert blew is None
    np.testing.assert_allclose(r.x, ref.x, atol=1e-9)


def test_blown_up_frames_are_not_drawn():
    fig = basics.mass_spring_demo("chain", dt=0.05, duration=1.0, method="semi_implicit_euler")
    ax = _left_panel(fig)
    assert "blew up" in ax.get_title() and "later frames not drawn" in ax.get_title()
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    assert x1 - x0 < 3 and y1 - y0 < 3  # the view stays on the rope (1 m), not on the blow-up


def test_stability_demo_keeps_large_h_lambda_in_view():
    fig = basics.stability_demo(dt=1.0, k=1e4)  # hλ = ±100 i
    for ax in fig.axes[:2]:
        assert ax.get_ylim()[1] > 100 and ax.get_ylim()[0] < -100
    fig = basics.stability_demo()  # small hλ: the default window
    assert fig.axes[0].get_xlim() == pytest.approx((-4.5, 2.5))


def test_ode_demo_energy_axis_resolves_small_drift():
    fig = basics.ode_demo(dt=0.001, method="rk4", t_end=2.0)
    ax = fig.axes[1]
    drift = np.abs(ax.lines[0].get_ydata()).max()
    assert 0 < drift < 1e-6
    assert ax.yaxis.get_transform().linthresh <= drift / 100  # the drift spans log decades


def test_ode_callbacks_validate_before_caching_and_reuse_runs(monkeypatch):
    for call, match in ((lambda: basics.ode_demo(dt=[0.02]), r"dt \(s\) must be a number"),
                        (lambda: basics.ode_demo(method=["rk4"]), "unknown method"),
                        (lambda: basics.stiff_spring_demo(dt=0.0), r"dt \(s\) must be > 0")):
        with pytest.raises((TypeError, ValueError), match=match):
            call()
    basics._run.cache_clear()
    calls = []
    real = basics.integrate
    monkeypatch.setattr(basics, "integrate", lambda *a, **k: calls.append(a[4]) or real(*a, **k))
    basics.stiff_spring_demo(k=4000.0, dt=0.02)
    basics.stiff_spring_demo(k=4000.0, dt=0.02)  # the same values: no new integration
    assert sorted(calls) == ["explicit_euler", "implicit_euler"]
