"""Demos for the course basics (lessons 01–03): ODE integrators and mass-spring systems.

Every ``*_demo`` function is a widget callback: keyword parameters in, a
:class:`matplotlib.figure.Figure` out, no global state. Lessons wire them to sliders with
:func:`physlab.viz.widgets.interact`; tests call them directly.

The running example is the slides' worked example (``../shared/seeds/004_…``, "An example"):
a particle of mass ``m`` on a spring of rest length ``L`` and stiffness ``k`` hanging from
the fixed point ``x̄0``, with damping ``-γ v`` and gravity ``-g M``, starting at
``y0 = (x̄0 + (0, -L), 0)``. It moves only vertically, so it has a closed-form solution.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure

from physlab import _check, springs
from physlab.integrators import (
    METHODS, MECHANICAL_METHODS, ORDER, SimulationDiverged, integrate, simulate,
    stability_function,
)
from physlab.linear_solver import LinearSolver, one_blas_thread
from physlab.springs import critical_time_step  # re-exported: lesson 03 imports it from here
from physlab.viz import plots

__all__ = [
    "HangingSpring", "convergence_study", "ode_demo", "convergence_demo", "newton_demo",
    "stiff_spring_demo", "stability_demo", "make_scene", "SCENES", "SCENE_DEFAULTS",
    "NEWTON_VARIANTS", "critical_time_step", "run_scene", "energy_comparison", "mass_spring_demo",
]


@dataclass(frozen=True)
class HangingSpring:
    """The slides' worked example as a first-order ODE ``y' = f(t, y)``, ``y = (x, v)`` in 2-D
    (slides eq. 9), with its exact solution.

    Units: m, kg, s; ``k`` N/m, ``gamma`` N·s/m, ``g`` m/s².
    """

    k: float = 40.0
    m: float = 1.0
    gamma: float = 0.0
    L: float = 1.0
    g: float = 9.81
    anchor: tuple = (0.0, 0.0)

    def __post_init__(self):
        for name, lo, open_ in (("k", 0, True), ("m", 0, True), ("gamma", 0, False),
                                ("L", 0, True), ("g", None, False)):
            object.__setattr__(self, name, _check.number(getattr(self, name), f"HangingSpring.{name}",
                                                         lo=lo, lo_open=open_))
        object.__setattr__(self, "anchor", tuple(_check.vector(self.anchor, "HangingSpring.anchor")))

    @property
    def y0(self):
        """``y0 = (x̄0 + (0, -L), 0)`` (slides "An example", initial values)."""
        return np.array([self.anchor[0], self.anchor[1] - self.L, 0.0, 0.0])

    @property
    def equilibrium(self):
        """Rest position ``x̄0 - (0, L + m g / k)``."""
        return np.array([self.anchor[0], self.anchor[1] - self.L - self.m * self.g / self.k])

    def forces(self, x, v):
        """``F^dp + F^int + G`` on the particle (slides "Forces")."""
        d = x - np.asarray(self.anchor)
        r = np.linalg.norm(d)
        return -self.gamma * v - self.k * (r - self.L) * d / r - self.m * np.array([0.0, self.g])

    def f(self, t, y):
        """Slides eq. (9): ``f(t, y) = (v, M^-1 F)``."""
        return np.concatenate([y[2:], self.forces(y[:2], y[2:]) / self.m])

    def jac(self, t, y):
        """Analytic ``df/dy`` (4×4)."""
        d = y[:2] - np.asarray(self.anchor)
        r = np.linalg.norm(d)
        n = d / r
        K = -self.k * ((1 - self.L / r) * np.eye(2) + self.L / r * np.outer(n, n))
        J = np.zeros((4, 4))
        J[:2, 2:] = np.eye(2)
        J[2:, :2] = K / self.m
        J[2:, 2:] = -self.gamma / self.m * np.eye(2)
        return J

    def energy(self, y):
        """Kinetic + spring + gravity energy of states ``y`` (..., 4)."""
        y = np.asarray(y)
        r = np.linalg.norm(y[..., :2] - np.asarray(self.anchor), axis=-1)
        return (0.5 * self.m * np.sum(y[..., 2:] ** 2, -1) + 0.5 * self.k * (r - self.L) ** 2
                + self.m * self.g * y[..., 1])

    def exact(self, t):
        """Exact ``y(t)`` (T, 4): a damped oscillation about the equilibrium along y
        (under-, critically or over-damped by ``ζ = γ / 2 sqrt(k m)``)."""
        t = np.asarray(t, float).reshape(-1)
        w0 = np.sqrt(self.k / self.m)
        zeta = self.gamma / (2 * np.sqrt(self.k * self.m))
        A = self.m * self.g / self.k  # starts A above equilibrium, at rest
        if abs(zeta - 1) < 1e-8:  # critical: u = A (1 + ω0 t) e^(-ω0 t)
            e = np.exp(-w0 * t)
            u, du = A * (1 + w0 * t) * e, -A * w0**2 * t * e
        elif zeta > 1:  # over-damped: two real decay rates r1, r2
            q = w0 * np.sqrt(zeta**2 - 1)
            r1, r2 = -zeta * w0 + q, -zeta * w0 - q
            e1, e2 = np.exp(r1 * t), np.exp(r2 * t)
            u = A * (r1 * e2 - r2 * e1) / (r1 - r2)
            du = A * r1 * r2 * (e2 - e1) / (r1 - r2)
        else:
            wd = w0 * np.sqrt(1 - zeta**2)
            decay = np.exp(-zeta * w0 * t)
            u = A * decay * (np.cos(wd * t) + zeta * w0 / wd * np.sin(wd * t))
            du = -A * decay * (w0**2 / wd) * np.sin(wd * t)
        y = np.zeros((t.size, 4))
        y[:, 0] = self.anchor[0]
        y[:, 1] = self.equilibrium[1] + u
        y[:, 3] = du
        return y

    def system(self):
        """The same scene as a :class:`physlab.springs.SpringSystem` (particle 1 moves)."""
        return springs.hanging_spring(self.anchor, self.L, self.k, self.m, self.gamma, self.g)


# ---------------------------------------------------------------------------- lesson 01/02

def _positive(value, name):
    """``value`` as a finite float > 0, else a ValueError/TypeError naming ``name``."""
    return _check.number(value, name, lo=0, lo_open=True)


def _check_choice(value, name, choices):
    if not isinstance(value, str) or value not in choices:
        raise ValueError(f"unknown {name} {value!r}; valid values are: {', '.join(choices)}")


def _two_panels(width, height, left=0.08, bottom=0.15, top=0.87, gap=0.10):
    """A ``width`` × ``height`` in figure with two side-by-side axes at fixed positions:
    constrained layout would double the drawing time of every widget redraw."""
    fig = Figure(figsize=(width, height))
    w = (1 - left - gap - 0.02) / 2
    a = fig.add_axes([left, bottom, w, top - bottom])  # [left, bottom, width, height]
    b = fig.add_axes([left + w + gap, bottom, w, top - bottom])
    return fig, (a, b)


@functools.lru_cache(maxsize=32)
def _run(problem, dt, method, t_end):
    """Integrate, returning ``(result, blew_up_step or None)``; a blow-up keeps the partial run.
    Cached (``problem`` is a frozen :class:`HangingSpring`): a widget redrawn with the same
    values, or another panel of the same run, does not integrate again. Callers must not modify
    the returned arrays."""
    try:
        return integrate(problem.f, problem.y0, (0.0, t_end), dt, method, jac=problem.jac), None
    except SimulationDiverged as err:
        return err.result, err.step


def ode_demo(dt=0.02, method="explicit_euler", t_end=10.0, k=40.0, m=1.0, gamma=0.0):
    """Height ``x_y(t)`` and total energy of the hanging spring: numerical vs exact.

    ``dt``, ``t_end`` in s (``t_end`` > 0); ``method`` one of :data:`METHODS`; ``k`` N/m,
    ``m`` kg, ``gamma`` N·s/m as in :class:`HangingSpring`."""
    p = HangingSpring(k=k, m=m, gamma=gamma)
    dt, t_end = _positive(dt, "dt (s)"), _positive(t_end, "t_end (s)")
    _check_choice(method, "method", METHODS)
    r, blew = _run(p, dt, method, t_end)
    te = np.linspace(0, t_end, 800)
    ex = p.exact(te)
    fig, (a, b) = _two_panels(8.0, 3.0, left=0.08, bottom=0.15, top=0.88, gap=0.11)
    a.plot(te, ex[:, 1], "k", lw=1, label="exact")
    a.plot(r.t, r.y[:, 1], ".-", ms=3, lw=0.8, color=plots.METHOD_COLORS[method], label=method)
    lo, hi = ex[:, 1].min(), ex[:, 1].max()
    pad = 0.6 * (hi - lo) + 0.05
    a.set_ylim(lo - pad, hi + pad)
    a.set_xlabel("t (s)")
    a.set_ylabel("height of the mass (m)")
    a.legend(fontsize=7, loc="lower right")
    E0 = p.energy(p.y0)
    with np.errstate(over="ignore", invalid="ignore"):
        dE = p.energy(r.y) - E0
    b.plot(r.t, dE, color=plots.METHOD_COLORS[method])
    dE_exact = p.energy(ex) - E0 if p.gamma > 0 else np.zeros(1)
    if p.gamma > 0:  # the exact motion loses energy to damping
        b.plot(te, dE_exact, "k", lw=1)
    else:  # it keeps it exactly (evaluating it would only draw round-off noise)
        b.axhline(0.0, color="k", lw=1)
    b.set_xlabel("t (s)")
    b.set_ylabel("E(t) - E(0) (J)")
    # symlog: decades of growth or decay stay readable; the linear band around 0 is narrower
    # than the drift (a 4th-order drift of 1e-11 J gets decade ticks too)
    shown = np.concatenate([dE[np.isfinite(dE)], dE_exact, [0.0]])
    drift = np.abs(shown).max()
    b.set_yscale("symlog", linthresh=max(1e-300, min(1e-3, drift / 1e3)) if drift > 0 else 1e-3)
    T = b.yaxis.get_transform()  # 5 % margins in the symlog coordinates, not in joules
    lo, hi = T.transform([shown.min(), shown.max()])
    pad = 0.05 * (hi - lo) if hi > lo else 1.0
    with np.errstate(over="ignore"):
        lims = np.clip(T.inverted().transform([lo - pad, hi + pad]), -1e300, 1e300)  # blow-ups
    half = 0.5 * T.linthresh  # one-signed drifts: no crowded ±linthresh tick beside 0
    if shown.min() >= 0:
        lims[0] = max(lims[0], -half)
    if shown.max() <= 0:
        lims[1] = min(lims[1], half)
    b.set_ylim(*lims)
    # readable ticks: at most ~8 decades labelled, none crowding the label "0"
    ticks = np.asarray(b.yaxis.get_major_locator()())
    ticks = ticks[(ticks >= lims[0]) & (ticks <= lims[1])]
    step = int(np.ceil(len(ticks) / 8))
    neg, pos = ticks[ticks < 0][::step], ticks[ticks > 0][::-1][::step]  # from the far ends
    t_ticks, (t_lo, t_hi) = T.transform(np.concatenate([neg, pos])), T.transform(lims)
    far = np.abs(t_ticks - T.transform([0.0])[0]) > 0.07 * (t_hi - t_lo)
    b.set_yticks(np.sort(np.concatenate([np.concatenate([neg, pos])[far], ticks[ticks == 0]])))
    title = f"{method}, dt = {dt:.3g} s, ω·dt = {np.sqrt(k / m) * dt:.2f}"
    if blew:
        title += f" — blew up at step {blew}"
    fig.suptitle(title, fontsize=9)
    return fig


def convergence_study(problem=None, methods=METHODS, dts=(0.01, 0.005, 0.0025, 0.00125), t_end=2.0):
    """Global error ``|y_n - y(t_end)|`` for each method and step: dict method -> (len(dts),).

    ``dts``: at least two different steps (s) > 0, to fit a slope; ``t_end`` (s) > 0."""
    try:
        dts = tuple(float(_positive(h, "each of dts (s)")) for h in dts)
    except TypeError as err:
        raise TypeError(f"dts must be a sequence of time steps (s), got {dts!r}: {err}") from None
    if len(set(dts)) < 2:
        raise ValueError(f"dts must hold at least two different time steps to measure an order, "
                         f"got {dts!r}")
    t_end = _positive(t_end, "t_end (s)")
    problem = problem or HangingSpring(gamma=0.5)
    exact = problem.exact([t_end])[0]
    return {m: np.array([np.linalg.norm(integrate(problem.f, problem.y0, (0.0, t_end), dt, m,
                                                  jac=problem.jac, tol=1e-13).y[-1] - exact)
                         for dt in dts]) for m in methods}


def convergence_demo(methods=METHODS, dts=(0.01, 0.005, 0.0025, 0.00125), t_end=2.0):
    """Log–log convergence plot; returns ``(fig, slopes)`` with the measured orders."""
    errors = convergence_study(methods=methods, dts=dts, t_end=t_end)
    fig, ax = plots.new_figure(width=5.0, height=3.8)
    slopes = plots.plot_convergence(ax, dts, errors, orders={m: ORDER[m] for m in methods})
    ax.set_title("hanging spring (slides' example), error at t = %g s" % t_end, fontsize=9)
    return fig, slopes


def newton_demo(dt=0.1, k=40.0, m=1.0, gamma=0.5, y0=None, max_iter=20):
    """Residual ``|G(y)|`` per Newton iteration in the first implicit Euler step of the
    worked example (slides eq. 12). Returns ``(fig, residuals)``."""
    p = HangingSpring(k=k, m=m, gamma=gamma)
    if y0 is None:
        y0 = p.y0
    else:
        try:
            y0 = np.asarray(y0, float)
        except (TypeError, ValueError):
            raise TypeError(f"y0 must be 4 numbers (x, y in m, v_x, v_y in m/s), got {y0!r}") from None
        if y0.shape != (4,) or not np.all(np.isfinite(y0)):
            raise ValueError(f"y0 must be 4 finite numbers (x, y in m, v_x, v_y in m/s), got {y0!r}")
    r = integrate(p.f, y0, (0.0, dt), dt, "implicit_euler", jac=p.jac, tol=1e-15, max_iter=max_iter)
    res = r.newton[0]
    fig, ax = plots.new_figure(width=4.5, height=3.2)
    plots.plot_newton_residuals(ax, res)
    ax.set_title(f"implicit Euler step, dt = {dt:g}: Newton–Raphson", fontsize=9)
    return fig, res


def stiff_spring_demo(k=4000.0, dt=0.02, t_end=2.0, m=1.0, gamma=0.5):
    """A stiff hanging spring with the same dt for explicit and implicit Euler.

    ``k`` N/m, ``dt`` and ``t_end`` s (> 0), ``m`` kg, ``gamma`` N·s/m."""
    p = HangingSpring(k=k, m=m, gamma=gamma)
    dt, t_end = _positive(dt, "dt (s)"), _positive(t_end, "t_end (s)")
    fig, ax = plots.new_figure(width=5.0, height=3.2)
    te = np.linspace(0, t_end, 2000)
    ax.plot(te, p.exact(te)[:, 1], "k", lw=0.8, label="exact")
    eq = p.equilibrium[1]
    half = 4 * m * 9.81 / k + 0.05  # plotted band around the equilibrium
    for method in ("explicit_euler", "implicit_euler"):
        r, blew = _run(p, dt, method, t_end)
        dev = np.abs(r.y[:, 1] - eq).max()
        note = f" (blew up at step {blew})" if blew else (f" (reaches {dev:.0e} m)" if dev > half else "")
        ax.plot(r.t, np.clip(r.y[:, 1], eq - 2 * half, eq + 2 * half), ".-", ms=3, lw=0.8,
                color=plots.METHOD_COLORS[method], label=method + note)
    ax.set_ylim(eq - half, eq + half)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("height of the mass (m)")
    ax.legend(fontsize=7)
    ax.set_title(f"k = {k:.3g} N/m, dt = {dt:.3g} s, ω·dt = {np.sqrt(k / m) * dt:.2f}", fontsize=9)
    return fig


def stability_demo(dt=0.05, k=40.0, m=1.0, gamma=0.5):
    """Stability regions ``|R(hλ)| <= 1`` of the explicit (left) and implicit (right) methods,
    with the spring's ``hλ`` marked (``λ`` roots of ``m λ² + γ λ + k = 0``).

    ``dt`` s > 0, ``k`` N/m > 0, ``m`` kg > 0, ``gamma`` N·s/m >= 0."""
    p = HangingSpring(k=k, m=m, gamma=gamma)
    dt = _positive(dt, "dt (s)")
    lam = np.roots([p.m, p.gamma, p.k]).astype(complex)
    z = dt * lam
    pts = {f"hλ{i + 1}": zi for i, zi in enumerate(z)}
    fig, (a, b) = _two_panels(7.2, 3.6, left=0.08, bottom=0.12, top=0.86, gap=0.10)
    # the default window (-4.5..2.5) × (-3.5..3.5), widened to keep large hλ in sight
    R = 1.15 * max(np.abs(z.real).max(), np.abs(z.imag).max())
    ext = (min(-4.5, -R), max(2.5, 0.6 * R), min(-3.5, -R), max(3.5, R))
    plots.plot_stability_regions(a, ("explicit_euler", "heun", "rk4"), extent=ext, points=pts)
    a.set_title("explicit (midpoint = heun)", fontsize=9)
    plots.plot_stability_regions(b, ("implicit_euler", "trapezoidal"), extent=ext, points=pts)
    b.set_title("implicit", fontsize=9)
    stable = [mm for mm in METHODS if np.all(np.abs(stability_function(mm, z)) <= 1 + 1e-12)]
    fig.suptitle(f"dt = {dt:.3g} s — stable here: " + (", ".join(stable) or "none"), fontsize=8)
    return fig


# ---------------------------------------------------------------------------- lesson 03

SCENES = ("hanging", "chain", "cloth", "soft_box")


#: Default (stiffness k in N/m, damping γ in N·s/m) of each scene.
SCENE_DEFAULTS = {"hanging": (40.0, 0.0), "chain": (600.0, 0.0), "cloth": (40.0, 0.0),
                  "soft_box": (2000.0, 0.1)}

#: Newton variants of implicit Euler (:func:`physlab.integrators.simulate`).
NEWTON_VARIANTS = ("full", "baraff_witkin")


def make_scene(scene="chain", k=None, damping=None):
    """Build one of :data:`SCENES` as a :class:`SpringSystem` with stiffness ``k`` (N/m, > 0;
    the structural springs, shear/bend scale with it) and damping ``γ`` (N·s/m, >= 0)
    (defaults: :data:`SCENE_DEFAULTS`)."""
    if not isinstance(scene, str) or scene not in SCENE_DEFAULTS:
        raise ValueError(f"unknown scene {scene!r}; valid scenes are: {', '.join(SCENES)}")
    k0, g0 = SCENE_DEFAULTS[scene]
    k = k0 if k is None else _positive(k, "k (N/m)")
    damping = g0 if damping is None else _check.number(damping, "damping γ (N·s/m)", lo=0)
    if scene == "hanging":
        return springs.hanging_spring(k=k, damping=damping)
    if scene == "chain":
        return springs.chain(12, length=1.0, k=k, total_mass=1.0, damping=damping)
    if scene == "cloth":  # held at one corner, so that it swings (two corners: it only sags)
        return springs.cloth_grid(8, 8, width=1.0, height=1.0, k=k, damping=damping,
                                  pin="top_left")
    return springs.soft_box(k=k, damping=damping)


def _check_system(system, name="system"):
    if not isinstance(system, springs.SpringSystem):
        raise TypeError(f"{name} must be a physlab.springs.SpringSystem (e.g. make_scene('chain')), "
                        f"got {type(system).__name__}")


class _DenseSolver(LinearSolver):
    """Solves the implicit-Euler systems ``(M - hD - h²K) dv = b`` with dense LAPACK
    (``numpy.linalg.solve``): exact, and for the lesson scenes (at most a few hundred
    unknowns) faster than sparse factors or preconditioned CG. Larger systems go to the
    sparse ``"lagged"`` solver."""

    DENSE_LIMIT = 600  # unknowns

    def __init__(self):
        super().__init__("lagged")

    def solve(self, A, b, x0=None, rtol=None):
        if A.shape[0] > self.DENSE_LIMIT:
            return super().solve(A, b, x0=x0, rtol=rtol)
        self.stats["solves"] += 1
        return np.linalg.solve(A.toarray(), b)


def run_scene(system, dt=0.005, duration=2.0, method="semi_implicit_euler", newton="full"):
    """Simulate a scene from rest for ``round(duration / dt)`` steps (``dt``, ``duration`` in s,
    > 0); a blow-up returns the partial run. Returns ``(result, blew_up_step or None)``.

    ``method``: one of :data:`MECHANICAL_METHODS`. Implicit Euler iterates Newton to
    convergence (``newton="full"``) or takes Baraff & Witkin's single linearised step
    (``"baraff_witkin"``: one linear solve per step, about half the cost); its linear
    systems are solved densely up to 600 unknowns (every lesson scene), else with the
    ``"lagged"`` solver (factors reused while they keep CG fast)."""
    _check_system(system)
    dt, duration = _positive(dt, "dt (s)"), _positive(duration, "duration (s)")
    _check_choice(method, "method", MECHANICAL_METHODS)
    _check_choice(newton, "newton", NEWTON_VARIANTS)
    x0, v0 = system.rest_state()
    n = max(1, int(round(duration / dt)))
    kw = {"solver": _DenseSolver(), "newton": newton} if method == "implicit_euler" else {}
    try:
        with one_blas_thread():  # the scenes' matrices are small: threads only cost
            return simulate(system, x0, v0, dt, n, method, **kw), None
    except SimulationDiverged as err:
        return err.result, err.step


@functools.lru_cache(maxsize=64)
def _scene_run(scene, k, damping, dt, duration, method, newton):
    """:func:`run_scene` of :func:`make_scene` ``(scene, k, damping)``, cached so that a widget
    redrawn after another control moved (e.g. the method) does not simulate again."""
    return run_scene(make_scene(scene, k=k, damping=damping), dt, duration, method, newton)


@functools.lru_cache(maxsize=64)
def _scene_energy(scene, k, damping, dt, duration, method, newton):
    """``(t, E, blew_up_step)`` of :func:`energy_comparison` for one cached run."""
    run = _scene_run(scene, k, damping, dt, duration, method, newton)
    return energy_comparison(make_scene(scene, k=k, damping=damping), dt, duration, (method,),
                             runs={method: run})[method]


@functools.lru_cache(maxsize=64)
def _scene_critical_dt(scene, k, damping):
    return critical_time_step(make_scene(scene, k=k, damping=damping))


def energy_comparison(system, dt=0.005, duration=2.0, methods=MECHANICAL_METHODS, runs=None):
    """Total energy (J) over time for each mechanical method: dict method ->
    ``(t (T,), E (T,), blew_up_step or None)``.

    ``runs``: optional dict method -> ``(result, blew_up_step)`` already simulated."""
    _check_system(system)
    for m in methods:
        _check_choice(m, "method", MECHANICAL_METHODS)
    out = {}
    for m in methods:
        r, blew = (runs or {}).get(m) or run_scene(system, dt, duration, m)
        with np.errstate(over="ignore", invalid="ignore"):
            E = np.array([system.energy(x, v) for x, v in zip(r.x, r.v)])
        out[m] = (r.t, E, blew)
    return out


def mass_spring_demo(scene="chain", k=None, damping=None, dt=0.004, method="semi_implicit_euler",
                     duration=1.5, compare=True, newton="baraff_witkin", max_steps=500):
    """Left: the scene under ``method`` — snapshots coloured by time (sparse scenes) or the last
    frame coloured by strain over the grey rest shape, with the path of the particle farthest
    from the pins (dense scenes); right: total energy (J) over time of all three mechanical
    methods at the same ``dt`` (``compare``), or of ``method`` alone. Curves that leave the
    plot (energy blow-up) are clipped and their fate is given in the legend.

    ``scene``, ``k`` (N/m), ``damping`` (N·s/m): :func:`make_scene`; ``dt``, ``duration`` in s.
    A widget callback: at most ``max_steps`` steps are simulated (``None``: no limit), so a tiny
    ``dt`` shows a shorter window (the title gives it); implicit Euler takes Baraff & Witkin's
    single linearised step by default (``newton``; see :func:`run_scene`); runs are cached.
    Axes in m; returns a :class:`matplotlib.figure.Figure` (8 × 3.4 in)."""
    s = make_scene(scene, k=k, damping=damping)
    dt, duration = _positive(dt, "dt (s)"), _positive(duration, "duration (s)")
    _check_choice(method, "method", MECHANICAL_METHODS)
    _check_choice(newton, "newton", NEWTON_VARIANTS)
    if not isinstance(compare, (bool, np.bool_)):
        raise TypeError(f"compare must be True or False, got {compare!r}")
    n = max(1, int(round(duration / dt)))
    if max_steps is not None:
        n = min(n, _check.number(max_steps, "max_steps", lo=1, integer=True))
    if n > 200_000:
        raise ValueError(f"duration / dt = {n} steps is too many for a widget (limit 200,000): "
                         f"use a larger dt or a shorter duration")
    key = (scene, None if k is None else float(k), None if damping is None else float(damping),
           dt, n * dt)
    r, blew = _scene_run(*key, method, newton)

    # fixed layout (constrained layout would double the drawing time of every redraw)
    fig = Figure(figsize=(8.0, 3.4))
    a = fig.add_axes([0.08, 0.30, 0.40, 0.57])  # [left, bottom, width, height] in figure units
    b = fig.add_axes([0.58, 0.14, 0.40, 0.73])
    cax = fig.add_axes([0.12, 0.10, 0.32, 0.03])
    # frames worth drawing: before a blow-up sends particles far away or stretches a spring
    # beyond 4× its rest length (soft cloth legitimately stretches by ~100 %)
    size = np.ptp(s.X, axis=0).max() + 1e-9
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        seg = r.x[:, s.edges]  # (T, E, 2, d)
        strain = np.linalg.norm(seg[:, :, 1] - seg[:, :, 0], axis=-1) / s.rest_length - 1
        ok = (np.abs(r.x - s.X).max(axis=(1, 2)) < 5 * size) & (np.abs(strain).max(axis=1) < 3.0)
    last = int(np.argmin(ok)) - 1 if not ok.all() else len(ok) - 1  # last frame of the sane prefix
    last = max(last, 0)
    if s.n <= 40:
        idx = np.unique(np.linspace(0, last, 6).round().astype(int))
        sm = plots.plot_snapshots(a, r.x, s.edges, idx, fixed=s.fixed, t=r.t)
        fig.colorbar(sm, cax=cax, orientation="horizontal",
                     label="snapshot time t (s): light = early, dark = late")
    else:  # dense scenes: rest shape in grey, last drawable frame coloured by strain
        plots.draw_springs(a, s.X, s.edges, color="0.85", particle_size=0)
        lc = plots.draw_springs(a, r.x[last], s.edges, fixed=s.fixed, particle_size=2,
                                rest_length=s.rest_length)
        pinned = s.X[np.asarray(s.fixed, int)] if len(s.fixed) else s.X[:1]
        far = int(np.argmax(np.min(np.linalg.norm(s.X[:, None] - pinned[None], axis=-1), axis=1)))
        a.plot(*r.x[: last + 1, far].T, color="tab:orange", lw=1, ls="--",
               label="path of the far corner")
        a.legend(fontsize=6.5, loc="lower left")
        a.set_aspect("equal")
        fig.colorbar(lc, cax=cax, orientation="horizontal",
                     label="strain l/L - 1 (grey: rest shape)")
    if s.ground is not None:
        a.axhline(s.ground, color="0.5")
    a.set_xlabel("x (m)", labelpad=1)
    a.set_ylabel("y (m)")
    (x0, x1), (y0, y1) = a.get_xlim(), a.get_ylim()
    w = max(x1 - x0, y1 - y0)  # tall scenes (a hanging spring is a line) keep room for ticks
    h = max(y1 - y0, 0.6 * w)  # and flat ones (a rope at rest) stay readable
    a.set_xlim((x0 + x1 - w) / 2, (x0 + x1 + w) / 2)
    a.set_ylim((y0 + y1 - h) / 2, (y0 + y1 + h) / 2)
    a.locator_params(axis="x", nbins=4)
    note = ""
    if blew:
        note = f"\nblew up at step {blew} (later frames not drawn)"
    elif last < len(r.t) - 1:
        note = "\nlater frames not drawn: a spring stretched > 4× its length"
    a.set_title(f"{scene}: {method}, t = {r.t[0]:.2f}–{r.t[last]:.2f} s" + note, fontsize=9)

    e0 = s.energy(*s.rest_state())
    E = {m: _scene_energy(*key, m, newton) for m in (MECHANICAL_METHODS if compare else (method,))}
    tame = [e for _, e, bl in E.values() if bl is None and np.ptp(e) < 10 * abs(e0) + 10]
    ref = np.concatenate(tame) if tame else np.array([e0 - 1.0, e0 + 1.0])
    lo, hi = min(ref.min(), e0), max(ref.max(), e0)
    pad = 0.15 * (hi - lo) + 1e-3
    for m, (t, e, bl) in E.items():
        label = m + (" (Baraff–Witkin)" if m == "implicit_euler" and newton == "baraff_witkin" else "")
        if bl:
            label += f" (blew up at step {bl})"
        elif e.max() > hi + pad:
            label += f" (leaves plot; E(end) = {e[-1]:.2g} J)"
        b.plot(t, np.clip(e, lo - 10 * pad, hi + 10 * pad), color=plots.METHOD_COLORS[m], label=label)
    b.axhline(e0, color="k", ls=":", lw=1, label="E(0)")
    b.set_ylim(lo - pad, hi + pad)
    b.set_xlabel("t (s)")
    b.set_ylabel("total energy (J)")
    b.legend(fontsize=6.5)
    b.set_title(f"k = {s.k.max():.3g} N/m, γ = {s.damping:.3g} N·s/m, dt = {dt:.3g} s, {n} steps\n"
                f"(critical 2/ω_max = {_scene_critical_dt(*key[:3]):.2g} s)", fontsize=8)
    return fig
