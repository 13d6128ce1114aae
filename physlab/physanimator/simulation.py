"""Simulate a PhysAnimator scene: Fixed Corotated FEM bodies advanced by semi-implicit Euler
(supp. Eq. 7, ``dt = 1e-3`` as in the paper), driven by energy strokes (Eqs. 8–9), rigs
(Eq. 10), gravity and contacts.

All bodies are stacked into one global mesh, so one vectorised :class:`~physlab.fem.CorotatedFEM`
evaluates every elastic force (per-triangle materials), and
:func:`physlab.integrators.simulate` performs the steps; rigs and contacts are applied by its
``project`` hook after each step.
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from physlab import _check, fem
from physlab.integrators import MAX_TRAJECTORY_BYTES, SimulationDiverged
from physlab.integrators import simulate as integrate_mechanical

from .collisions import resolve_body_contacts, resolve_half_planes
from .rigging import WavyRig

__all__ = ["simulate", "Animation", "SceneSystem", "UnstableTimeStep", "safe_time_step",
           "measured_stable_dt"]


class UnstableTimeStep(SimulationDiverged):
    """The run blew up (non-finite state, speeds beyond any physical motion of the scene, or
    blow-up growth — see :func:`physlab.integrators.simulate`); ``safe_dt`` is a CFL-like
    step (s) that should work.

    As a :class:`~physlab.integrators.SimulationDiverged` it names the ``step`` (``1`` = the
    first), its start time ``t`` (s), the ``dt`` and ``method`` in use and carries the partial
    run: ``result`` is an :class:`Animation` of the frames stored before the blow-up."""

    def __init__(self, message, safe_dt, step=None, t=None, dt=None, method=None, result=None):
        FloatingPointError.__init__(self, message)
        self.safe_dt, self.step, self.t, self.dt = safe_dt, step, t, dt
        self.method, self.result, self.reason = method, result, message


def _check_scene(scene):
    from .scene import Scene

    if not isinstance(scene, Scene):
        raise TypeError(f"scene must be a physlab.physanimator.Scene, got "
                        f"{type(scene).__name__} (load JSON with Scene.from_json)")
    return scene


def safe_time_step(scene, safety=0.5):
    """Stable explicit step (s) for the scene: the smallest over bodies of the CFL-like
    ``safety · h_min / c`` (:func:`physlab.fem.stable_time_step`), and ``2 safety / damping``
    (the damping term ``v ← (1 - dt·damping) v`` is stable for ``dt·damping < 2``);
    ``safety`` in (0, 1]."""
    _check_scene(scene)
    safety = _check.number(safety, "safety", lo=0, hi=1, lo_open=True)
    cfl = min(fem.stable_time_step(b.mesh.X, b.mesh.tris, b.material.E, b.material.nu,
                                   b.material.rho, safety) for b in scene.bodies)
    return min(cfl, 2 * safety / scene.damping) if scene.damping > 0 else cfl


def _min_height(X, tris):
    """Smallest triangle height (px) of a mesh: ``2 V / longest edge``."""
    e = np.stack([X[tris[:, 1]] - X[tris[:, 0]], X[tris[:, 2]] - X[tris[:, 1]],
                  X[tris[:, 0]] - X[tris[:, 2]]], 1)
    area = 0.5 * np.abs(e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0])
    return float(np.min(2 * area / np.linalg.norm(e, axis=2).max(1)))


def _likely_causes(scene, system, dt):
    """Scene parameters that make explicit steps of ``dt`` unstable, as readable hints: strong
    damping, external accelerations (gravity, strokes) or wavy rigs that move vertices by a
    sizeable part of the smallest triangle per step."""
    h = min(_min_height(b.mesh.X, b.mesh.tris) for b in scene.bodies)
    hints = []
    if scene.damping * dt > 1:
        hints.append(f"damping {scene.damping:g}/s × dt = {scene.damping * dt:.3g} (explicit "
                     f"steps need damping·dt < 2)")
    g = float(np.hypot(*scene.gravity))
    if g * dt**2 > 0.5 * h:
        hints.append(f"gravity {g:.3g} px/s² moves vertices {g * dt**2:.3g} px per step (the "
                     f"smallest triangle is {h:.3g} px high)")
    m_min = float(system.mass.min())
    for i, st in enumerate(scene.strokes):
        a = abs(st.strength) / m_min
        if a * dt**2 > 0.5 * h:
            hints.append(f"strokes[{i}] (strength {st.strength:.3g}) accelerates the lightest "
                         f"vertex by {a:.3g} px/s², {a * dt**2:.3g} px per step (the smallest "
                         f"triangle is {h:.3g} px high)")
    for i, r in enumerate(scene.rigs):
        if isinstance(r, WavyRig) and abs(r.amplitude * r.frequency) * dt > 0.5 * h:
            hints.append(f"rigs[{i}] (WavyRig, amplitude {r.amplitude:g} px, frequency "
                         f"{r.frequency:.3g} rad/s) moves its vertices up to "
                         f"{abs(r.amplitude * r.frequency) * dt:.3g} px per step")
    return hints


def measured_stable_dt(scene, duration=0.5, rel_tol=0.05, method="semi_implicit_euler"):
    """The largest step (s) at which :func:`simulate` runs ``scene`` for ``duration`` without
    blowing up, measured: doubling from :func:`safe_time_step` until a run fails, then
    bisection (in log dt) to ``rel_tol``. The CFL estimate is conservative; this says by how
    much, for this scene. Returns ``(dt_stable, dt_estimate)``; ``dt_stable`` is capped at
    64 × the estimate."""
    _check_scene(scene)
    duration = _check.number(duration, "duration (s)", lo=0, lo_open=True)
    rel_tol = _check.number(rel_tol, "rel_tol", lo=1e-6, hi=1.0)
    est = safe_time_step(scene)

    def stable(dt):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                simulate(scene, duration, dt=dt, progress=False, method=method)
                return True
            except UnstableTimeStep:
                return False

    lo, hi = 0.0, None
    for factor in (1, 2, 4, 8, 16, 32, 64):
        if not stable(factor * est):
            hi = factor * est
            break
        lo = factor * est
    if hi is None:
        return lo, est
    if lo == 0.0:
        lo = est / 64
    while hi / lo > 1 + rel_tol:
        mid = float(np.sqrt(lo * hi))
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo, est


class SceneSystem:
    """The scene as one mechanical system for :func:`physlab.integrators.simulate`:
    ``mass`` (n,), ``force(x, v, t)`` (n, 2), ``fixed`` (pinned vertices of fixed rigs)."""

    def __init__(self, scene):
        self.scene = scene
        Xs, Ts, mus, lams, ms, offsets = [], [], [], [], [], [0]
        for b in scene.bodies:
            X, tris = b.X_canvas, b.mesh.tris
            mu, lam = fem.lame_parameters(b.material.E, b.material.nu)
            Xs.append(X)
            Ts.append(tris + offsets[-1])
            mus.append(np.full(len(tris), mu))
            lams.append(np.full(len(tris), lam))
            ms.append(fem.lumped_masses(X, tris, b.material.rho))  # Eq. (3)
            offsets.append(offsets[-1] + len(X))
        self.X = np.concatenate(Xs)
        self.tris = np.concatenate(Ts)
        self.offsets = offsets
        self.mass = np.concatenate(ms)
        self.model = fem.CorotatedFEM(self.X, self.tris, np.concatenate(mus), np.concatenate(lams))
        self.gravity = np.asarray(scene.gravity, dtype=float)
        fixed, self.wavy = [], []
        for rig in scene.rigs:
            lo = offsets[rig.body]
            idx = rig.select(scene.bodies[rig.body].X_canvas) + lo
            (self.wavy.append((idx, rig)) if isinstance(rig, WavyRig) else fixed.append(idx))
        self.fixed = np.unique(np.concatenate(fixed)) if fixed else np.zeros(0, int)
        self.contact_bodies = []
        for i, b in enumerate(scene.bodies):
            lo = offsets[i]
            self.contact_bodies.append(dict(idx=np.arange(lo, offsets[i + 1]), tris=b.mesh.tris + lo,
                                            boundary=b.mesh.boundary_vertices() + lo,
                                            edges=b.mesh.boundary_edges() + lo))
        self.planes = scene.half_planes()
        self.contacts = 0
        self.dt = None  # set by simulate(); lets contacts find where a vertex came in
        # contacts treat pinned and rigged vertices as kinematic (infinite mass)
        self.inv_mass_contact = 1.0 / self.mass
        self.inv_mass_contact[self.fixed] = 0.0
        for idx, _ in self.wavy:
            self.inv_mass_contact[idx] = 0.0

    def body_slice(self, i):
        return slice(self.offsets[i], self.offsets[i + 1])

    def force(self, x, v, t):
        """``f_int(x) + f_ext(x)`` (Eq. 1): elastic (Eq. 4), gravity, strokes (Eqs. 8–9), damping."""
        f = self.model.forces(x)
        f += self.mass[:, None] * self.gravity
        f -= self.scene.damping * self.mass[:, None] * v
        for stroke in self.scene.strokes:
            f += stroke.forces(x, t)
        return f

    def force_jacobians(self, x, v, t):
        """``(K, D)`` for implicit Euler: the elastic stiffness (FEM, beyond the paper) and the
        damping ``-damping · M``. The strokes' dependence on ``x`` is left out: Newton then
        runs with an approximate Jacobian and converges to the same step, a little slower."""
        import scipy.sparse as sp

        K = self.model.stiffness(x)
        D = sp.diags(np.repeat(-self.scene.damping * self.mass, 2), format="csr")
        return K, D

    def project(self, t, x, v):
        """After-step constraints (in place): wavy rigs (Eq. 10), ground/walls, body contacts."""
        # positions before the step: both integrators end with x_{k+1} = x_k + dt v_{k+1}
        x_prev = x - self.dt * v if self.dt else None
        for idx, rig in self.wavy:
            disp, vel = rig.offset(t)
            x[idx] = self.X[idx] + disp
            v[idx] = vel
        s = self.scene
        if self.planes:
            self.contacts += resolve_half_planes(x, v, self.planes, s.restitution, s.friction)
        if s.collisions and len(self.contact_bodies) > 1:
            self.contacts += resolve_body_contacts(x, v, self.inv_mass_contact, self.contact_bodies,
                                                   s.restitution, s.friction, x_prev=x_prev)

    def elastic_energy(self, x):
        return self.model.energy(x)


@dataclass
class Animation:
    """Result of :func:`simulate`: frame times ``t`` (F,), per-body vertex positions
    ``x[b]`` (F, n_b, 2) on the canvas, and run statistics."""

    t: np.ndarray
    x: list
    scene: object
    dt: float
    fps: float
    stats: dict = field(default_factory=dict)

    @property
    def n_frames(self):
        return len(self.t)

    def frame(self, k):
        """Positions of every body at frame ``k``: list of (n_b, 2)."""
        return [xb[k] for xb in self.x]


#: Largest number of time steps :func:`simulate` runs (``duration / dt``).
MAX_STEPS = 10_000_000


def simulate(scene, duration, dt=1e-3, fps=24, progress=True, check_dt=True,
             method="semi_implicit_euler"):
    """Simulate ``scene`` for ``duration`` seconds with semi-implicit Euler (Eq. 7), or with
    ``method="implicit_euler"`` (beyond the paper: Newton on the FEM stiffness, for stiff
    materials and steps far above the explicit limit).

    Frames are stored every ``round(1 / (fps dt))`` steps. With ``check_dt`` a step larger
    than the CFL estimate warns, and speeds beyond any physical motion of the scene
    (``max(20 c, 50 |canvas|, 10 |v0|)``, ``c`` the fastest wave speed, px/s) count as a
    blow-up. A blow-up (that, a non-finite state, or blow-up growth of the positions) raises
    :class:`UnstableTimeStep` naming the step and a safe ``dt``, with the frames stored before
    it. Returns an :class:`Animation`.

    Arguments are checked before anything runs: ``scene`` a :class:`Scene`, ``duration`` (s)
    and ``dt`` (s) finite and > 0, ``0 < fps <= 1000``, at most :data:`MAX_STEPS` steps and
    at most 2 GB of stored frames (ValueError / TypeError naming the argument).
    """
    _check_scene(scene)
    duration = _check.number(duration, "duration (s)", lo=0, lo_open=True)
    dt = _check.number(dt, "dt (s)", lo=0, lo_open=True)
    fps = _check.number(fps, "fps", lo=0, hi=1000, lo_open=True)
    if method not in ("semi_implicit_euler", "implicit_euler"):
        raise ValueError(f"unknown method {method!r}; valid: semi_implicit_euler, implicit_euler")
    if duration / dt > MAX_STEPS:
        raise ValueError(f"duration {duration:g} s at dt = {dt:g} s is {duration / dt:,.0f} "
                         f"steps, more than the limit of {MAX_STEPS:,}; shorten the run or use "
                         f"a larger dt (or method='implicit_euler')")
    n_vertices = sum(len(b.mesh.X) for b in scene.bodies)
    n_frames = duration * min(fps, 1.0 / dt) + 1
    need = 2 * 2 * 8 * n_frames * n_vertices           # positions and velocities, float64
    if need > MAX_TRAJECTORY_BYTES:
        raise ValueError(f"{n_frames:,.0f} frames of {n_vertices:,} vertices need "
                         f"{need / 1e9:.3g} GB, more than the limit of "
                         f"{MAX_TRAJECTORY_BYTES / 1e9:.3g} GB; lower fps ({fps:g} now), shorten "
                         f"the run or use coarser meshes")
    system = SceneSystem(scene)
    system.dt = dt
    safe = safe_time_step(scene)
    if check_dt and method == "semi_implicit_euler" and dt > 2 * safe:
        warnings.warn(f"dt = {dt:g} s is above the stability estimate {safe:.2g} s "
                      "(CFL: smallest triangle / wave speed); the run may blow up", stacklevel=2)
    every = max(1, int(round(1.0 / (fps * dt))))  # steps per stored frame
    n_steps = max(1, int(round(duration / (every * dt)))) * every
    c_max = 0.0  # fastest dilatational wave speed sqrt((λ + 2μ)/ρ) of the scene (px/s)
    for b in scene.bodies:
        mu, lam = fem.lame_parameters(b.material.E, b.material.nu)
        c_max = max(c_max, float(np.sqrt((lam + 2 * mu) / b.material.rho)))
    v0_max = max([float(np.hypot(*b.velocity)) for b in scene.bodies]
                 + [r.amplitude * r.frequency for r in scene.rigs if isinstance(r, WavyRig)])
    v_limit = max(20 * c_max, 50 * float(np.hypot(*scene.size)), 10 * v0_max)  # px/s

    x0 = system.X.copy()
    v0 = np.concatenate([np.broadcast_to(np.asarray(b.velocity, float), (len(b.mesh.X), 2))
                         for b in scene.bodies])
    t0 = time.perf_counter()
    try:
        # implicit Newton stops at 1e-6 of its first residual, or at the round-off level of
        # the scene's momentum scale (total mass moving one canvas diagonal per second)
        atol = 1e-9 * system.mass.sum() * float(np.hypot(*scene.size))
        run = integrate_mechanical(system, x0, v0, dt, n_steps, method=method, atol=atol,
                                   max_iter=50, project=system.project, save_every=every,
                                   progress=progress, max_speed=v_limit if check_dt else None)
    except SimulationDiverged as err:
        partial = _animation(err.result, system, scene, dt, every, dict(
            steps=err.step - 1, steps_per_frame=every, contacts=system.contacts, method=method,
            seconds=time.perf_counter() - t0, safe_dt=safe, vertices=len(x0),
            triangles=len(system.tris)))
        reason = err.reason.replace("max_speed", "the scene's speed limit") + " px/s" \
            if "max_speed" in err.reason else err.reason
        causes = _likely_causes(scene, system, dt)
        if dt > safe or not causes:
            todo = (f"use dt <= {safe:.2g} s (stability estimate from the smallest triangle, "
                    f"the wave speed and the damping), soften the material or use "
                    f"method='implicit_euler'")
        else:
            todo = (f"dt is already within the stability estimate ({safe:.2g} s) of the "
                    f"material: weaken those or take much smaller steps")
        why = f"; likely causes: {'; '.join(causes)}" if causes else ""
        raise UnstableTimeStep(
            f"the simulation blew up at step {err.step} (t = {err.t:.4g} s, dt = {dt:g} s, "
            f"method '{method}'): {reason}{why}; {todo}",
            safe, err.step, err.t, dt, method, partial) from None
    stats = dict(steps=n_steps, steps_per_frame=every, contacts=system.contacts, method=method,
                 seconds=time.perf_counter() - t0, safe_dt=safe, vertices=len(x0),
                 triangles=len(system.tris))
    return _animation(run, system, scene, dt, every, stats)


def _animation(run, system, scene, dt, every, stats):
    """An :class:`Animation` of an integrator result: per-body slices of ``run.x``."""
    xs = [run.x[:, system.body_slice(i)] for i in range(len(scene.bodies))]
    return Animation(run.t, xs, scene, dt, 1.0 / (every * dt), stats)
