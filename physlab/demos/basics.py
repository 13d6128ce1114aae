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

from dataclasses import dataclass

import functools

import numpy as np

from physlab import springs
from physlab.integrators import (
    METHODS, MECHANICAL_METHODS, ORDER, SimulationDiverged, integrate, simulate, stability_function,
)
from physlab.viz import plots

__all__ = [
    "HangingSpring", "convergence_study", "ode_demo", "convergence_demo", "newton_demo",
    "stiff_spring_demo", "stability_demo", "make_scene", "SCENES", "SCENE_DEFAULTS", "critical_time_step", "run_scene", "energy_comparison",
    "mass_spring_demo",
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

def _run(problem, dt, method, t_end):
    """Integrate, returning ``(result, blew_up_step or None)``; a blow-up keeps the partial run."""
    try:
        return integrate(problem.f, problem.y0, (0.0, t_end), dt, method, jac=problem.jac), None
    except SimulationDiverged as err:
        return err.result, err.step


def ode_demo(dt=0.02, method="explicit_euler", t_end=10.0, k=40.0, m=1.0, gamma=0.0):
    """Height ``x_y(t)`` and total energy of the hanging spring: numerical vs exact."""
    p = HangingSpring(k=k, m=m, gamma=gamma)
    r, blew = _run(p, dt, method, t_end)
    te = np.linspace(0, t_end, 800)
    ex = p.exact(te)
    fig, (a, b) = plots.new_figure(2, 1, width=4.0, height=3.0)
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
    b.plot(te, p.energy(ex) - E0, "k", lw=1)
    b.set_xlabel("t (s)")
    b.set_ylabel("E(t) - E(0) (J)")
    b.set_yscale("symlog", linthresh=max(1e-9, min(1e-3, np.nanmax(np.abs(dE[np.isfinite(dE)])) / 10)))
    title = f"{method}, dt = {dt:.3g} s, ω·dt = {np.sqrt(k / m) * dt:.2f}"
    if blew:
        title += f" — blew up at step {blew}"
    fig.suptitle(title, fontsize=9)
    return fig


def convergence_study(problem=None, methods=METHODS, dts=(0.01, 0.005, 0.0025, 0.00125), t_end=2.0):
    """Global error ``|y_n - y(t_end)|`` for each method and step: dict method -> (len(dts),)."""
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
    y0 = p.y0 if y0 is None else np.asarray(y0, float)
    r = integrate(p.f, y0, (0.0, dt), dt, "implicit_euler", jac=p.jac, tol=1e-15, max_iter=max_iter)
    res = r.newton[0]
    fig, ax = plots.new_figure(width=4.5, height=3.2)
    plots.plot_newton_residuals(ax, res)
    ax.set_title(f"implicit Euler step, dt = {dt:g}: Newton–Raphson", fontsize=9)
    return fig, res


def stiff_spring_demo(k=4000.0, dt=0.02, t_end=2.0, m=1.0, gamma=0.5):
    """A stiff hanging spring with the same dt for explicit and implicit Euler."""
    p = HangingSpring(k=k, m=m, gamma=gamma)
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
    with the spring's ``hλ`` marked (``λ`` roots of ``m λ² + γ λ + k = 0``)."""
    lam = np.roots([m, gamma, k]).astype(complex)
    z = dt * lam
    pts = {f"hλ{i + 1}": zi for i, zi in enumerate(z)}
    fig, (a, b) = plots.new_figure(2, 1, width=3.6, height=3.6)
    plots.plot_stability_regions(a, ("explicit_euler", "heun", "rk4"), points=pts)
    a.set_title("explicit (midpoint = heun)", fontsize=9)
    plots.plot_stability_regions(b, ("implicit_euler", "trapezoidal"), points=pts)
    b.set_title("implicit", fontsize=9)
    stable = [mm for mm in METHODS if np.all(np.abs(stability_function(mm, z)) <= 1 + 1e-12)]
    fig.suptitle(f"dt = {dt:.3g} s — stable here: " + (", ".join(stable) or "none"), fontsize=8)
    return fig


# ---------------------------------------------------------------------------- lesson 03

SCENES = ("hanging", "chain", "cloth", "soft_box")


#: Default (stiffness k in N/m, damping γ in N·s/m) of each scene.
SCENE_DEFAULTS = {"hanging": (40.0, 0.0), "chain": (600.0, 0.0), "cloth": (40.0, 0.0),
                  "soft_box": (2000.0, 0.1)}


def make_scene(scene="chain", k=None, damping=None):
    """Build one of :data:`SCENES` as a :class:`SpringSystem` with stiffness ``k`` (the
    structural springs; shear/bend scale with it) and damping ``γ`` (defaults:
    :data:`SCENE_DEFAULTS`)."""
    if scene not in SCENE_DEFAULTS:
        raise ValueError(f"unknown scene {scene!r}; valid scenes are: {', '.join(SCENES)}")
    k0, g0 = SCENE_DEFAULTS[scene]
    k = k0 if k is None else float(k)
    damping = g0 if damping is None else float(damping)
    if scene == "hanging":
        return springs.hanging_spring(k=k, damping=damping)
    if scene == "chain":
        return springs.chain(12, length=1.0, k=k, total_mass=1.0, damping=damping)
    if scene == "cloth":  # held at one corner, so that it swings (two corners: it only sags)
        return springs.cloth_grid(8, 8, width=1.0, height=1.0, k=k, damping=damping,
                                  pin="top_left")
    return springs.soft_box(k=k, damping=damping)


def run_scene(system, dt=0.005, duration=2.0, method="semi_implicit_euler"):
    """Simulate a scene from rest; a blow-up returns the partial run. Returns
    ``(result, blew_up_step or None)``. Implicit Euler solves its Newton systems with the
    ``"lagged"`` solver (factors reused while they keep CG fast): the same steps to the same
    tolerance as a fresh factorisation, about twice as fast on these small scenes."""
    x0, v0 = system.rest_state()
    n = int(round(duration / dt))
    kw = {"solver": "lagged"} if method == "implicit_euler" else {}
    try:
        return simulate(system, x0, v0, dt, n, method, **kw), None
    except SimulationDiverged as err:
        return err.result, err.step


@functools.lru_cache(maxsize=64)
def _scene_run(scene, k, damping, dt, duration, method):
    """:func:`run_scene` of :func:`make_scene` ``(scene, k, damping)``, cached so that a widget
    redrawn after another control moved (e.g. the method) does not simulate again."""
    return run_scene(make_scene(scene, k=k, damping=damping), dt, duration, method)


def critical_time_step(system):
    """``2 / ω_max``: the largest stable step of semi-implicit (symplectic) Euler for the
    linearised, undamped system at rest (``ω_max²`` = largest eigenvalue of ``-M^-1 K`` over
    the free particles). Explicit Euler has no such step without damping: it gains energy at
    every ``dt`` (lesson 01). Dense eigenvalues: for lesson-sized systems (≲ 1,000 dofs)."""
    from scipy.linalg import eigh

    x, v = system.rest_state()
    K, _ = system.force_jacobians(x, v)
    d = system.d
    free = np.setdiff1d(np.arange(system.n), system.fixed)
    dofs = (free[:, None] * d + np.arange(d)).ravel()
    Kf = -K.toarray()[np.ix_(dofs, dofs)]
    m = np.repeat(system.mass, d)[dofs]
    w2 = eigh(0.5 * (Kf + Kf.T), np.diag(m), eigvals_only=True)[-1]
    return float(2.0 / np.sqrt(max(w2, 1e-300)))


def energy_comparison(system, dt=0.005, duration=2.0, methods=MECHANICAL_METHODS, runs=None):
    """Total energy over time for each mechanical method: dict method -> (t, E, blew_up_step).

    ``runs``: optional dict method -> ``(result, blew_up_step)`` already simulated."""
    out = {}
    for m in methods:
        r, blew = (runs or {}).get(m) or run_scene(system, dt, duration, m)
        with np.errstate(over="ignore", invalid="ignore"):
            E = np.array([system.energy(x, v) for x, v in zip(r.x, r.v)])
        out[m] = (r.t, E, blew)
    return out


def mass_spring_demo(scene="chain", k=None, damping=None, dt=0.004, method="semi_implicit_euler",
                     duration=1.5, compare=True):
    """Left: snapshots of the scene under ``method``; right: energy over time of all three
    mechanical methods at the same dt (``compare``), or of ``method`` alone. Curves that
    leave the plot (energy blow-up) are clipped and their fate is given in the legend."""
    s = make_scene(scene, k=k, damping=damping)
    key = (scene, None if k is None else float(k), None if damping is None else float(damping),
           float(dt), float(duration))
    r, blew = _scene_run(*key, method)
    fig, (a, b) = plots.new_figure(2, 1, width=4.0, height=3.4)
    size = np.ptp(s.X, axis=0).max() + 1e-9
    sane = np.flatnonzero(np.abs(r.x - s.X).max(axis=(1, 2)) < 5 * size)  # frames worth drawing
    if s.n <= 40:
        idx = np.unique(np.linspace(0, sane[-1], 6).round().astype(int))
        sm = plots.plot_snapshots(a, r.x, s.edges, idx, fixed=s.fixed, t=r.t)
        fig.colorbar(sm, ax=a, orientation="horizontal", shrink=0.6, pad=0.15,
                     label="snapshot time t (s): light = early, dark = late")
    else:  # dense scenes: rest shape in grey, last drawable frame coloured by strain
        plots.draw_springs(a, s.X, s.edges, color="0.85", particle_size=0)
        lc = plots.draw_springs(a, r.x[sane[-1]], s.edges, fixed=s.fixed, particle_size=2,
                                rest_length=s.rest_length)
        fig.colorbar(lc, ax=a, orientation="horizontal", shrink=0.6, label="strain l/L - 1")
    if s.ground is not None:
        a.axhline(s.ground, color="0.5")
    a.set_xlabel("x (m)")
    a.set_ylabel("y (m)")
    a.locator_params(axis="x", nbins=4)
    a.set_title(f"{scene}: {method}, t = {r.t[sane[-1]]:.2f} s"
                + (f", blew up at step {blew}" if blew else ""), fontsize=9)
    e0 = s.energy(*s.rest_state())
    E = energy_comparison(s, dt, duration, MECHANICAL_METHODS if compare else (method,),
                          runs={m: _scene_run(*key, m) for m in MECHANICAL_METHODS})
    tame = [e for _, e, bl in E.values() if bl is None and np.ptp(e) < 10 * abs(e0) + 10]
    ref = np.concatenate(tame) if tame else np.array([e0 - 1.0, e0 + 1.0])
    lo, hi = min(ref.min(), e0), max(ref.max(), e0)
    pad = 0.15 * (hi - lo) + 1e-3
    for m, (t, e, bl) in E.items():
        label = m
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
    kk = s.k.max()
    b.set_title(f"k = {kk:.3g} N/m, γ = {s.damping:.3g}, dt = {dt:.3g} s\n"
                f"(critical 2/ω_max = {critical_time_step(s):.2g} s)", fontsize=8)
    return fig
