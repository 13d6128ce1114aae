"""Time integrators: generic ODE steppers and steppers for mechanical systems.

Two entry points, both pure functions (state in, trajectory out):

* :func:`integrate` solves a first-order initial value problem ``y' = f(t, y)``,
  ``y(t0) = y0`` with a fixed step. It is what the course slides build up from Newton's
  law: writing ``y = (x, v)`` turns ``x'' = M^-1 F`` (slides eq. 1) into the first-order
  system ``y' = (v, M^-1 F)`` (slides eq. 2).
* :func:`simulate` advances a second-order mechanical system (``mass``, ``force``, and for
  implicit Euler ``force_jacobians``) such as :class:`physlab.springs.SpringSystem`.

Each scheme is one small step function (``*_step``: :data:`STEPS` for :func:`integrate`,
:data:`MECHANICAL_STEPS` for :func:`simulate`) that the time loop picks once and calls at
every step. The sparse linear solves of implicit Euler live in :mod:`physlab.linear_solver`.

References
----------
[slides] T. Popa, "Animation for Computer Games — Physics-based Animation", COMP 477/6311
    (``../shared/seeds/004_b49e6b3b92bd43c3.txt``): eqs. 1–7, 9, 12.
[PA] PhysAnimator supplementary (``000_0a4fa540c2202b0e.txt``), Eq. (7): semi-implicit Euler.
[BW] D. Baraff and A. Witkin, "Large steps in cloth simulation", SIGGRAPH 1998, Eq. (6).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .linear_solver import ConvergenceError, LinearSolver

__all__ = [
    "METHODS",
    "MECHANICAL_METHODS",
    "ConvergenceError",
    "SimulationDiverged",
    "NewtonResult",
    "ODEResult",
    "SimulationResult",
    "LinearSolver",
    "newton_solve",
    "finite_difference_jacobian",
    "integrate",
    "STEPS",
    "explicit_euler_step",
    "midpoint_step",
    "heun_step",
    "rk4_step",
    "implicit_euler_step",
    "trapezoidal_step",
    "simulate",
    "MECHANICAL_STEPS",
    "mechanical_explicit_euler_step",
    "mechanical_semi_implicit_euler_step",
    "mechanical_implicit_euler_step",
    "stability_function",
    "convergence_order",
]

#: Methods of :func:`integrate` (explicit ones first).
METHODS = ("explicit_euler", "midpoint", "heun", "rk4", "implicit_euler", "trapezoidal")
#: Methods of :func:`simulate`.
MECHANICAL_METHODS = ("explicit_euler", "semi_implicit_euler", "implicit_euler")
IMPLICIT_METHODS = ("implicit_euler", "trapezoidal")
#: Classical order of accuracy of each method of :func:`integrate`.
ORDER = {"explicit_euler": 1, "midpoint": 2, "heun": 2, "rk4": 4, "implicit_euler": 1, "trapezoidal": 2}


#: :func:`simulate` raises :class:`SimulationDiverged` when a particle gets this many times
#: farther from its start than the initial velocities and accelerations can take it ...
GROWTH_LIMIT = 1e3
#: ... and its displacement grew faster than any low power of time: more than this factor
#: since the step ``2^j`` in ``(k/4, k/2]`` (``t^p`` motion grows at most ``4^p``; a blow-up
#: grows exponentially).
GROWTH_RATIO = 1e4
#: Largest number of steps :func:`simulate` and :func:`integrate` accept (fail fast instead
#: of running for days).
MAX_STEPS = 50_000_000
#: Largest memory (bytes) :func:`simulate` / :func:`integrate` may allocate for the stored
#: trajectory; beyond it they refuse before allocating (use ``save_every`` / a larger dt).
MAX_TRAJECTORY_BYTES = 2 * 1024**3


class SimulationDiverged(FloatingPointError):
    """The simulation blew up: the state became non-finite, or (for :func:`simulate`) the
    positions grew far beyond anything the initial state and forces can explain.

    Attributes
    ----------
    step : int
        Index of the step whose result was not finite or too large (``1`` = the first step).
    t : float
        Time at the start of that step.
    dt : float
        Step size in use.
    result : ODEResult or SimulationResult
        The trajectory up to and including the last finite state, for plotting.
    """

    def __init__(self, step: int, t: float, dt: float, method: str, result,
                 reason="the state is no longer finite"):
        self.step, self.t, self.dt, self.method, self.result = step, t, dt, method, result
        self.reason = reason
        hint = (
            "use a smaller dt or an implicit method ('implicit_euler')"
            if method not in IMPLICIT_METHODS
            else "use a smaller dt"
        )
        super().__init__(
            f"simulation blew up at step {step} (t = {t:.6g}, dt = {dt:g}, method '{method}'): "
            f"{reason}; {hint}"
        )


@dataclass
class NewtonResult:
    """Solution of ``G(z) = 0`` by :func:`newton_solve`.

    ``residuals[k]`` is ``|G(z_k)|`` (Euclidean norm) before iteration ``k``; the last entry
    belongs to the returned ``z``.
    """

    z: np.ndarray
    residuals: list
    iterations: int
    converged: bool


@dataclass
class ODEResult:
    """Trajectory of :func:`integrate`: ``t`` ``(n+1,)``, ``y`` ``(n+1, d)``.

    ``newton`` holds, for implicit methods, one list of Newton residual norms per step.
    ``nfev`` counts evaluations of ``f``.
    """

    t: np.ndarray
    y: np.ndarray
    method: str
    dt: float
    nfev: int = 0
    newton: list = field(default_factory=list)


@dataclass
class SimulationResult:
    """Trajectory of :func:`simulate`: ``t`` ``(n_steps+1,)``, ``x`` and ``v`` ``(n_steps+1, n, d)``.

    ``newton`` holds, for ``implicit_euler``, one list of Newton residual norms per step.
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    method: str
    dt: float
    newton: list = field(default_factory=list)


# ----------------------------------------------------------------------------------------
# validation helpers


def _check_dt(dt) -> float:
    try:
        dt = float(dt)
    except (TypeError, ValueError):
        raise TypeError(f"dt must be a number, got {dt!r}") from None
    if not np.isfinite(dt) or dt <= 0:
        raise ValueError(f"dt must be a finite number > 0, got {dt}")
    return dt


def _check_method(method, valid) -> str:
    if method not in valid:
        raise ValueError(f"unknown method {method!r}; valid methods are: {', '.join(valid)}")
    return method


def _check_count(value, name, lo=0, hi=None) -> int:
    """``value`` as an int in ``[lo, hi]`` (floats with integral values are accepted)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer, float,
                                                                     np.floating)):
        raise TypeError(f"{name} must be an integer, got {value!r} ({type(value).__name__})")
    if not np.isfinite(value) or int(value) != value or value < lo:
        need = "a non-negative integer" if lo == 0 else f"an integer >= {lo}"
        raise ValueError(f"{name} must be {need}, got {value!r}")
    value = int(value)
    if hi is not None and value > hi:
        raise ValueError(f"{name} = {value:,} is more than the limit of {hi:,}")
    return value


def _check_tolerance(value, name) -> float:
    """A finite float >= 0 (Newton tolerances)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer,
                                                                     np.floating)):
        raise TypeError(f"{name} must be a number, got {value!r}")
    if not np.isfinite(value) or value < 0:
        raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
    return float(value)


def _check_memory(n_states, state_size, name, what_to_do):
    """Refuse trajectories of more than :data:`MAX_TRAJECTORY_BYTES` before allocating."""
    need = 8.0 * n_states * state_size
    if need > MAX_TRAJECTORY_BYTES:
        raise ValueError(f"{name}: storing {n_states:,} states of {state_size:,} numbers needs "
                         f"{need / 1e9:.3g} GB, more than the limit of "
                         f"{MAX_TRAJECTORY_BYTES / 1e9:.3g} GB; {what_to_do}")


def _as_state(value, name) -> np.ndarray:
    """``value`` as a float array; a ragged or non-numeric input is named."""
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array, got {type(value).__name__} that numpy "
                         f"cannot turn into floats (ragged or non-numeric)") from None


def _check_finite(name: str, a: np.ndarray) -> None:
    if not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))[0]
        raise ValueError(f"{name} contains NaN or inf (first at index {tuple(int(i) for i in bad)})")


# ----------------------------------------------------------------------------------------
# Newton–Raphson


def _solve(A, b):
    """Solve ``A z = b`` for dense or sparse ``A``."""
    if sp.issparse(A):
        return spla.spsolve(sp.csc_matrix(A), b)
    return np.linalg.solve(A, b)


def _backtrack(G, z, dz, r, line_search=True):
    """Newton update ``z + s dz`` with the largest ``s`` in ``1, 1/2, 1/4, ...`` satisfying
    Armijo's condition on ``phi = |G|^2 / 2`` (whose slope along ``dz`` is ``-|G|^2``):
    ``|G(z + s dz)|^2 <= (1 - 2e-4 s) |G(z)|^2``. Returns ``(z_new, G(z_new), |G(z_new)|, s)``;
    ``s < 1e-10`` means the search failed (``dz`` is not a descent direction)."""
    s = 1.0
    while True:
        z_new = z + s * dz
        with np.errstate(all="ignore"):
            g_new = np.asarray(G(z_new), dtype=float)
        r_new = float(np.linalg.norm(g_new))
        if not line_search or (np.isfinite(r_new) and r_new**2 <= (1 - 2e-4 * s) * r**2):
            return z_new, g_new, r_new, s
        s *= 0.5
        if s < 1e-10:
            return z_new, g_new, r_new, s


def newton_solve(
    G: Callable[[np.ndarray], np.ndarray],
    J: Callable[[np.ndarray], np.ndarray],
    z0: np.ndarray,
    tol: float = 1e-10,
    max_iter: int = 50,
    line_search: bool = True,
    raise_on_failure: bool = True,
) -> NewtonResult:
    """Solve the nonlinear system ``G(z) = 0`` by Newton–Raphson with backtracking.

    Each iteration solves ``J(z) dz = -G(z)`` and takes ``z + s dz`` with the largest
    ``s`` in ``1, 1/2, 1/4, ...`` that decreases the merit ``|G|^2/2`` enough (Armijo
    condition with constant 1e-4). Near the solution the full step is accepted and the
    residual falls quadratically.

    Parameters
    ----------
    G : callable ``z (m,) -> (m,)``
    J : callable ``z (m,) -> (m, m)`` dense array or scipy sparse matrix, ``dG/dz``.
    z0 : (m,) float array, initial guess.
    tol : stop when ``|G(z)| <= tol * max(1, |G(z0)|)`` (Euclidean norms).
    max_iter : iteration cap.
    line_search : backtrack (True) or always take the full step (False).
    raise_on_failure : raise :class:`ConvergenceError` when not converged (default).

    Returns
    -------
    NewtonResult with the residual history (one norm per iterate).
    """
    z = np.array(z0, dtype=float)
    g = np.asarray(G(z), dtype=float)
    r = float(np.linalg.norm(g))
    residuals = [r]
    target = tol * max(1.0, r)
    it = 0
    while r > target and it < max_iter:
        try:
            with np.errstate(all="ignore"):
                dz = _solve(J(z), -g)
        except np.linalg.LinAlgError:  # singular Jacobian: reported below as non-convergence
            break
        if not np.all(np.isfinite(dz)):
            break
        z, g, r, _ = _backtrack(G, z, dz, r, line_search)
        residuals.append(r)
        it += 1
        if not np.isfinite(r):
            break
    converged = bool(np.isfinite(r) and r <= target)
    if not converged and raise_on_failure:
        raise ConvergenceError(
            f"Newton–Raphson did not converge in {it} iterations "
            f"(residual {r:.3e}, target {target:.3e}); try a smaller dt, a larger max_iter "
            f"or check the Jacobian. Residual history: "
            + ", ".join(f"{x:.2e}" for x in residuals[-8:]),
            residuals,
        )
    return NewtonResult(z, residuals, it, converged)


def finite_difference_jacobian(f: Callable, t: float, y: np.ndarray, eps: float | None = None):
    """Central-difference Jacobian ``df/dy`` of ``f(t, y)`` at ``y``, shape ``(d, d)``.

    Step per component ``eps * max(1, |y_i|)`` with ``eps = cbrt(machine eps) ≈ 6e-6`` by
    default (balances truncation and round-off for central differences).
    """
    y = np.asarray(y, dtype=float)
    if eps is None:
        eps = np.finfo(float).eps ** (1 / 3)
    d = y.size
    Jm = np.empty((d, d))
    for i in range(d):  # 2d evaluations of f; fine for the small systems it is used on
        h = eps * max(1.0, abs(y[i]))
        e = np.zeros(d)
        e[i] = h
        Jm[:, i] = (np.asarray(f(t, y + e)) - np.asarray(f(t, y - e))) / (2 * h)
    return Jm


# ----------------------------------------------------------------------------------------
# first-order ODEs


def _identity_like(Jf, d):
    return sp.identity(d, format="csr") if sp.issparse(Jf) else np.eye(d)


# One step of each scheme, ``y_k -> y_{k+1}``: ``f`` is a callable ``(t, y (d,)) -> (d,)``
# float array, ``t`` the time at the start of the step, ``y`` the state ``(d,)`` float array
# there, ``dt`` (``h``) the step > 0; each returns ``y_{k+1}`` ``(d,)``. :func:`integrate`
# calls the one of its ``method`` at every step.


def explicit_euler_step(f, t, y, dt):
    """Explicit (forward) Euler, slides eq. (3)–(4): ``y_{k+1} = y_k + h f(t_k, y_k)``.

    First order; one evaluation of ``f``. ``y`` ``(d,)`` -> ``y_{k+1}`` ``(d,)``."""
    return y + dt * f(t, y)  # eq. (3)


def midpoint_step(f, t, y, dt):
    """Explicit midpoint rule: ``y_{k+1} = y_k + h f(t_k + h/2, y_k + h/2 f_k)``, the Taylor
    step of slides eq. (5) to second order with ``ÿ`` as the difference quotient of eq. (6).

    Second order; two evaluations of ``f``. ``y`` ``(d,)`` -> ``y_{k+1}`` ``(d,)``."""
    fk = f(t, y)
    return y + dt * f(t + dt / 2, y + dt / 2 * fk)  # eq. (5) with eq. (6)


def heun_step(f, t, y, dt):
    """Heun's method: ``y_{k+1} = y_k + h/2 (f_k + f(t_{k+1}, y_k + h f_k))``, the trapezoidal
    rule of slides eq. (7) with the unknown ``ẏ_{k+1}`` predicted by an explicit Euler step.

    Second order; two evaluations of ``f``. ``y`` ``(d,)`` -> ``y_{k+1}`` ``(d,)``."""
    fk = f(t, y)
    return y + dt / 2 * (fk + f(t + dt, y + dt * fk))  # eq. (7), predictor-corrector


def rk4_step(f, t, y, dt):
    """Classical 4th-order Runge–Kutta:
    ``y_{k+1} = y_k + h/6 (k_1 + 2 k_2 + 2 k_3 + k_4)`` with ``k_1 = f(t_k, y_k)``,
    ``k_2 = f(t_k + h/2, y_k + h/2 k_1)``, ``k_3 = f(t_k + h/2, y_k + h/2 k_2)``,
    ``k_4 = f(t_k + h, y_k + h k_3)``: it agrees with the Taylor series that slides eq. (5)
    stops after ``h^2`` up to the ``h^4`` term.

    Fourth order; four evaluations of ``f``. ``y`` ``(d,)`` -> ``y_{k+1}`` ``(d,)``."""
    k1 = f(t, y)
    k2 = f(t + dt / 2, y + dt / 2 * k1)
    k3 = f(t + dt / 2, y + dt / 2 * k2)
    k4 = f(t + dt, y + dt * k3)
    return y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def implicit_euler_step(f, t, y, dt, jac=None, tol=1e-10, max_iter=50, line_search=True,
                        history=None):
    """Implicit (backward) Euler, slides eq. (12): ``y_{k+1} = y_k + h f(t_{k+1}, y_{k+1})``.

    Solves ``G(z) = z - y_k - h f(t_{k+1}, z) = 0`` by :func:`newton_solve` (Jacobian
    ``I - h J_f``) from the explicit Euler predictor ``y_k + h f_k``. First order, stable for
    every ``h`` on decaying problems.

    Parameters
    ----------
    f, t, y, dt : ``f(t, y) -> (d,)``, the time, the state ``(d,)`` and the step > 0.
    jac : callable ``(t, y) -> (d, d)`` dense or sparse ``df/dy``; central finite
        differences (:func:`finite_difference_jacobian`) when None.
    tol, max_iter, line_search : :func:`newton_solve` settings.
    history : optional list; the step appends its Newton residual norms (one list) to it.

    Returns
    -------
    ``y_{k+1}`` ``(d,)``. When ``f(t, y)`` is not finite there is nothing to solve: that
    non-finite value is returned for the caller to report.

    Raises
    ------
    ConvergenceError when Newton fails.
    """
    fk = f(t, y)
    return _implicit_step(f, t, y, dt, fk, y, 1.0, jac, tol, max_iter, line_search,
                          history)  # eq. (12)


def trapezoidal_step(f, t, y, dt, jac=None, tol=1e-10, max_iter=50, line_search=True,
                     history=None):
    """Trapezoidal rule (implicit), slides eq. (7):
    ``y_{k+1} = y_k + h/2 (f(t_k, y_k) + f(t_{k+1}, y_{k+1}))``.

    Solves ``G(z) = z - y_k - h/2 f_k - h/2 f(t_{k+1}, z) = 0`` by :func:`newton_solve`
    (Jacobian ``I - h/2 J_f``) from the explicit Euler predictor. Second order; arguments,
    result and errors as :func:`implicit_euler_step`."""
    fk = f(t, y)
    return _implicit_step(f, t, y, dt, fk, y + dt / 2 * fk, 0.5, jac, tol, max_iter,
                          line_search, history)  # eq. (7)


def _implicit_step(f, t, y, h, fk, rhs, c, jac, tol, max_iter, line_search, history):
    """``z`` with ``G(z) = z - rhs - c h f(t + h, z) = 0`` by Newton from ``y + h f_k``."""
    if not np.all(np.isfinite(fk)):
        return fk  # non-finite: reported by the caller
    tn, d = t + h, y.size

    def G(z):
        return z - rhs - c * h * f(tn, z)  # eq. (12) / eq. (7) as a root problem

    def JG(z):
        Jz = finite_difference_jacobian(f, tn, z) if jac is None else jac(tn, z)
        return _identity_like(Jz, d) - c * h * Jz

    res = newton_solve(G, JG, y + h * fk, tol=tol, max_iter=max_iter, line_search=line_search)
    if history is not None:
        history.append(res.residuals)
    return res.z


#: The step function of each method of :func:`integrate`.
STEPS = {"explicit_euler": explicit_euler_step, "midpoint": midpoint_step, "heun": heun_step,
         "rk4": rk4_step, "implicit_euler": implicit_euler_step,
         "trapezoidal": trapezoidal_step}


def integrate(
    f: Callable[[float, np.ndarray], np.ndarray],
    y0,
    t_span: tuple[float, float],
    dt: float,
    method: str = "explicit_euler",
    jac: Callable | None = None,
    tol: float = 1e-10,
    max_iter: int = 50,
    line_search: bool = True,
    progress: bool = False,
) -> ODEResult:
    """Integrate ``y' = f(t, y)`` from ``t_span[0]`` to ``t_span[1]`` with fixed step ``dt``.

    Methods (``h = dt``, ``f_k = f(t_k, y_k)``):

    ``"explicit_euler"``  ``y_{k+1} = y_k + h f_k``                          slides eq. (3)–(4)
    ``"midpoint"``        ``y_{k+1} = y_k + h f(t_k + h/2, y_k + h/2 f_k)``   2nd order, from eq. (5)
                          with ``ÿ`` as the difference quotient of eq. (6)
    ``"heun"``            ``y_{k+1} = y_k + h/2 (f_k + f(t_{k+1}, y_k + h f_k))``
                          eq. (7) with the unknown ``ẏ_{k+1}`` predicted by an Euler step
    ``"rk4"``             classical 4th-order Runge–Kutta
    ``"implicit_euler"``  ``y_{k+1} = y_k + h f(t_{k+1}, y_{k+1})``          slides eq. (12)
    ``"trapezoidal"``     ``y_{k+1} = y_k + h/2 (f_k + f(t_{k+1}, y_{k+1}))`` eq. (7), implicit

    The implicit methods solve their nonlinear equation ``G(y_{k+1}) = 0`` with
    :func:`newton_solve`, Jacobian ``I - c h J_f`` (``c = 1`` or ``1/2``) from ``jac`` or
    by central finite differences, starting from an explicit Euler predictor.
    One step of each method is a function of its own (:data:`STEPS`):
    :func:`explicit_euler_step`, :func:`midpoint_step`, :func:`heun_step`, :func:`rk4_step`,
    :func:`implicit_euler_step`, :func:`trapezoidal_step`.

    Parameters
    ----------
    f : callable ``(t, y (d,)) -> (d,)``.
    y0 : (d,) initial state (a scalar is treated as ``d = 1``).
    t_span : ``(t0, t1)`` with ``t1 > t0``. The last step is shortened to end exactly at
        ``t1`` when ``(t1 - t0) / dt`` is not an integer.
    dt : step size > 0.
    jac : callable ``(t, y) -> (d, d)`` dense or sparse ``df/dy``; finite differences when None.
    tol, max_iter, line_search : Newton settings (implicit methods only).
    progress : show a tqdm progress bar.

    Returns
    -------
    ODEResult with ``t`` ``(n+1,)`` and ``y`` ``(n+1, d)``; for implicit methods
    ``newton[k]`` is the residual history of step ``k``.

    Raises
    ------
    ValueError for bad input; SimulationDiverged when the state stops being finite (the
    partial trajectory is attached); ConvergenceError when Newton fails.
    """
    _check_method(method, METHODS)
    dt = _check_dt(dt)
    if not callable(f):
        raise TypeError(f"f must be a function f(t, y) -> (d,), got {type(f).__name__}")
    if jac is not None and not callable(jac):
        raise TypeError(f"jac must be None or a function jac(t, y) -> (d, d), got "
                        f"{type(jac).__name__}")
    tol = _check_tolerance(tol, "tol")
    max_iter = _check_count(max_iter, "max_iter", lo=1)
    y0 = np.atleast_1d(_as_state(y0, "y0"))
    if y0.ndim != 1:
        raise ValueError(f"y0 must be a 1-D state vector, got shape {y0.shape}; flatten it first")
    _check_finite("y0", y0)
    try:
        t0, t1 = (float(s) for s in t_span)
    except (TypeError, ValueError):
        raise ValueError(f"t_span must be a pair (t0, t1), got {t_span!r}") from None
    if not (np.isfinite(t0) and np.isfinite(t1)) or t1 <= t0:
        raise ValueError(f"t_span must satisfy t0 < t1 (finite), got ({t0}, {t1})")

    n_float = np.ceil((t1 - t0) / dt - 1e-9)
    if n_float > MAX_STEPS:
        raise ValueError(f"t_span ({t0:g}, {t1:g}) at dt = {dt:g} is {n_float:,.0f} steps, more "
                         f"than the limit of {MAX_STEPS:,}; use a larger dt or a shorter t_span")
    n = int(n_float)
    _check_memory(n + 1, y0.size, "integrate", "use a larger dt or a shorter t_span")
    t = t0 + dt * np.arange(n + 1)
    t[-1] = t1
    d = y0.size
    y = np.empty((n + 1, d))
    y[0] = y0
    nfev = 0

    def F(tt, yy):
        nonlocal nfev
        nfev += 1
        raw = f(tt, yy)
        try:
            out = np.asarray(raw, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"f(t, y) must return numbers of shape ({d},) like y0, got "
                             f"{type(raw).__name__} {raw!r:.60}") from None
        if out.shape != (d,):
            out = out.reshape(-1)
            if out.shape != (d,):
                raise ValueError(f"f(t, y) must return shape ({d},) like y0, got {np.shape(out)}")
        return out

    def Jf(tt, yy):
        Jm = jac(tt, yy)
        if Jm.shape != (d, d):
            raise ValueError(f"jac(t, y) must return shape ({d}, {d}), got {Jm.shape}")
        return Jm

    newton_hist = []
    step = STEPS[method]  # the scheme, chosen once
    options = {}
    if method in IMPLICIT_METHODS:
        options = dict(jac=None if jac is None else Jf, tol=tol, max_iter=max_iter,
                       line_search=line_search, history=newton_hist)
    steps = range(n)
    if progress:
        from tqdm.auto import tqdm

        steps = tqdm(steps, desc=method, leave=False)
    for k in steps:
        tk, h = t[k], t[k + 1] - t[k]
        with np.errstate(over="ignore", invalid="ignore"):
            try:
                yn = step(F, tk, y[k], h, **options)
            except ConvergenceError as err:
                raise ConvergenceError(f"{method} step {k + 1} (t = {tk:.6g}): {err}",
                                       err.residuals) from None
        if not np.all(np.isfinite(yn)):
            partial = ODEResult(t[: k + 1].copy(), y[: k + 1].copy(), method, dt, nfev, newton_hist)
            raise SimulationDiverged(k + 1, tk, dt, method, partial)
        y[k + 1] = yn
    return ODEResult(t, y, method, dt, nfev, newton_hist)


# ----------------------------------------------------------------------------------------
# mechanical systems  M x'' = f(x, v, t)


def _fixed_indices(system, n):
    fixed = np.asarray(getattr(system, "fixed", ()), dtype=int).reshape(-1)
    if fixed.size and (fixed.min() < 0 or fixed.max() >= n):
        raise ValueError(f"system.fixed refers to particles outside 0..{n - 1}")
    return np.unique(fixed)


def _implicit_matrix(M_flat, K, D, h, pinned_dofs):
    """``A = M - h D - h^2 K`` as CSR, with pinned rows/columns replaced by identity rows.

    When ``K`` and ``D`` share one sparsity pattern that contains the diagonal (as
    :class:`physlab.springs.SpringSystem` guarantees) the data arrays are combined directly.
    """
    K = sp.csr_matrix(K)
    D = sp.csr_matrix(D)
    N = K.shape[0]
    if K.shape == D.shape and np.array_equal(K.indptr, D.indptr) and np.array_equal(K.indices, D.indices):
        A = sp.csr_matrix((-h * h * K.data - h * D.data, K.indices, K.indptr), shape=K.shape)
    else:
        A = sp.csr_matrix((-h * h) * K - h * D)
    A.sort_indices()
    rows = np.repeat(np.arange(N), np.diff(A.indptr))
    on_diag = rows == A.indices
    M_eff = M_flat.copy()
    M_eff[pinned_dofs] = 1.0  # keeps the diagonal entry of pinned rows even for massless ones
    if np.count_nonzero(on_diag) == N:
        A.data[on_diag] += M_eff  # one diagonal entry per row, in row order
    else:
        A = sp.csr_matrix(A + sp.diags(M_eff))
        rows = np.repeat(np.arange(N), np.diff(A.indptr))
        on_diag = rows == A.indices
    if pinned_dofs.size:
        pin = np.zeros(N, bool)
        pin[pinned_dofs] = True
        hit = pin[rows] | pin[A.indices]
        A.data[hit] = 0.0
        A.data[hit & on_diag] = 1.0
    return A


# One step of each scheme, ``(x_k, v_k) -> (x_{k+1}, v_{k+1})``: ``force(x, v, t) -> (n, d)``
# (N), ``inv_m`` ``(n,)`` inverse masses (1/kg; 0 for pinned particles), positions ``x`` and
# velocities ``v`` ``(n, d)`` float arrays (m, m/s) at time ``t`` (s), ``dt`` (``h``) the step
# (s) > 0; each returns new arrays ``(x_{k+1}, v_{k+1})``, both ``(n, d)``. :func:`simulate`
# calls the one of its ``method`` at every step, then projects and pins.


def mechanical_explicit_euler_step(force, inv_m, x, v, t, dt):
    """Explicit Euler for ``y = (x, v)``, slides eq. (4):
    ``x_{k+1} = x_k + h v_k``, ``v_{k+1} = v_k + h M^-1 f(x_k, v_k, t_k)``.

    First order; gains energy on every undamped oscillation, at any ``h``."""
    a = force(x, v, t) * inv_m[:, None]
    xn = x + dt * v  # eq. (4)
    vn = v + dt * a
    return xn, vn


def mechanical_semi_implicit_euler_step(force, inv_m, x, v, t, dt):
    """Semi-implicit (symplectic) Euler, PhysAnimator supp. Eq. (7):
    ``v_{k+1} = v_k + h M^-1 f(x_k, v_k, t_k)``, ``x_{k+1} = x_k + h v_{k+1}``.

    First order; its energy error stays bounded while ``h`` is below ``2 / ω_max``
    (:func:`physlab.springs.critical_time_step`)."""
    vn = v + dt * force(x, v, t) * inv_m[:, None]  # PhysAnimator Eq. (7)
    xn = x + dt * vn
    return xn, vn


def mechanical_implicit_euler_step(system, force, x, v, t, dt, M_flat, pinned_dofs,
                                   newton="full", tol=1e-6, atol=1e-10, max_iter=20,
                                   solver=None, dv_guess=None, history=None):
    """Implicit Euler for ``y = (x, v)``, slides eq. (12):
    ``v_{k+1} = v_k + h M^-1 f(x_{k+1}, v_{k+1}, t_{k+1})``, ``x_{k+1} = x_k + h v_{k+1}``.

    The unknown is ``v' = v_{k+1}``, a root of ``G(v') = M (v' - v_k) - h f(x_k + h v', v')``
    with Jacobian ``M - h D - h^2 K`` (``K = df/dx``, ``D = df/dv`` from
    ``system.force_jacobians``). First the linearised step of [BW] Eq. (6),
    ``(M - h D - h^2 K) dv = h (f_k + h K v_k)`` with ``K, D`` at ``(x_k, v_k)``: the answer
    for ``newton="baraff_witkin"``; ``newton="full"`` iterates Newton from there until
    ``|G| <= max(tol |G(v_k)|, atol)`` (``G`` in N·s), each linear solve only as accurate as
    the iteration needs (inexact Newton, Eisenstat–Walker).

    Parameters
    ----------
    system : has ``force_jacobians(x, v, t) -> (K, D)`` sparse ``(n*d, n*d)``.
    force : ``force(x, v, t) -> (n, d)`` (N), e.g. ``system.force``.
    x, v, t, dt : positions and velocities ``(n, d)``, time (s), step (s) > 0.
    M_flat : ``(n*d,)`` masses per unknown (kg), ``np.repeat(mass, d)``.
    pinned_dofs : int array of the unknowns (``particle * d + axis``) held fixed.
    newton, tol, atol, max_iter : as :func:`simulate`.
    solver : a :class:`LinearSolver` (kept across steps for its factors); None: a new
        ``LinearSolver("auto")``.
    dv_guess : optional ``(n*d,)`` warm start of iterative solvers (the previous step's
        velocity change).
    history : optional list; the step appends its residual norms ``|G|`` (one list) to it.

    Returns
    -------
    ``(x_{k+1}, v_{k+1})``, both ``(n, d)``.

    Raises
    ------
    ConvergenceError when full Newton does not reach its target.
    """
    if solver is None:
        solver = LinearSolver()
    n, d = x.shape
    vk = v.reshape(-1)
    h = dt  # the slides' notation
    tn = t + h
    # Baraff–Witkin linearised step at (x_k, v_k): (M - hD - h^2 K) dv = h (f_k + h K v_k)
    K, D = system.force_jacobians(x, v, t)
    A = _implicit_matrix(M_flat, K, D, h, pinned_dofs)
    b = h * (force(x, v, t).reshape(-1) + h * (K @ vk))
    b[pinned_dofs] = 0.0
    # the linearised step is the answer for Baraff–Witkin, only a starting guess for full
    # Newton (whose iterations correct it): solve it loosely there
    dv = solver.solve(A, b, x0=dv_guess, rtol=None if newton == "baraff_witkin" else 1e-4)
    z = vk + dv

    def G(zz):
        g = M_flat * (zz - vk) - h * force(x + h * zz.reshape(n, d), zz.reshape(n, d), tn).reshape(-1)
        g[pinned_dofs] = 0.0
        return g

    g = G(z)
    hist = [float(np.linalg.norm(G(vk))), float(np.linalg.norm(g))]
    if newton == "full":
        target = max(tol * hist[0], atol)  # relative to the first residual, absolute floor
        it = 0
        r, r_prev = hist[-1], hist[0]
        while r > target and it < max_iter and np.isfinite(r):
            K, D = system.force_jacobians(x + h * z.reshape(n, d), z.reshape(n, d), tn)
            A = _implicit_matrix(M_flat, K, D, h, pinned_dofs)
            # inexact Newton (Eisenstat–Walker choice 2): loose linear solves far from the
            # solution, never tighter than needed to reach the target in this iteration
            eta = min(0.1, 0.9 * (r / r_prev) ** 2)
            dz = solver.solve(A, -g, rtol=max(solver.rtol, eta, 0.5 * target / r))
            r_prev = r
            z_old = z
            z, g, r, step = _backtrack(G, z, dz, r)
            hist.append(r)
            it += 1
            # a full Newton step that changes nothing at round-off level: the residual is as
            # small as floating point allows (a failed line search is *not* this)
            stalled = step == 1.0 and np.linalg.norm(z - z_old) <= 1e-13 * np.linalg.norm(z)
            if stalled or step < 1e-10:
                break
        else:
            stalled = False
        if np.isfinite(r) and r > target and not stalled:
            raise ConvergenceError(
                f"implicit Euler: Newton did not converge at t = {t:.6g} in {it} iterations "
                f"(residual {r:.3e} > {target:.3e}); use a smaller dt or a larger max_iter", hist)
    if history is not None:
        history.append(hist)
    vn = z.reshape(n, d)
    xn = x + dt * vn  # eq. (12): x_{k+1} = x_k + h v_{k+1}
    return xn, vn


#: The step function of each method of :func:`simulate`.
MECHANICAL_STEPS = {"explicit_euler": mechanical_explicit_euler_step,
                    "semi_implicit_euler": mechanical_semi_implicit_euler_step,
                    "implicit_euler": mechanical_implicit_euler_step}


def simulate(
    system,
    x0,
    v0,
    dt: float,
    n_steps: int,
    method: str = "semi_implicit_euler",
    t0: float = 0.0,
    newton: str = "full",
    tol: float = 1e-6,
    atol: float = 1e-10,
    max_iter: int = 20,
    solver: str = "auto",
    progress: bool = False,
    project=None,
    save_every: int = 1,
    max_speed: float | None = None,
) -> SimulationResult:
    """Advance ``M x'' = f(x, v, t)`` by ``n_steps`` steps of size ``dt``: Newton's law
    ``ẍ = M⁻¹F`` (slides eq. (1)) as the first-order system ``ẏ = (v, M⁻¹F)`` (eq. (2)).

    Methods (``h = dt``, ``f_k = f(x_k, v_k, t_k)``):

    ``"explicit_euler"``       ``x_{k+1} = x_k + h v_k``,  ``v_{k+1} = v_k + h M^-1 f_k``
                               (slides eq. 4)
    ``"semi_implicit_euler"``  ``v_{k+1} = v_k + h M^-1 f_k``,  ``x_{k+1} = x_k + h v_{k+1}``
                               (symplectic Euler; PhysAnimator supp. Eq. 7)
    ``"implicit_euler"``       ``v_{k+1} = v_k + h M^-1 f(x_{k+1}, v_{k+1}, t_{k+1})``,
                               ``x_{k+1} = x_k + h v_{k+1}`` (slides eq. 12 for ``y = (x, v)``)

    One step of each method is a function of its own (:data:`MECHANICAL_STEPS`):
    :func:`mechanical_explicit_euler_step`, :func:`mechanical_semi_implicit_euler_step`,
    :func:`mechanical_implicit_euler_step`. Implicit Euler solves for ``v' = v_{k+1}`` with
    Newton on ``G(v') = M (v' - v_k) - h f(x_k + h v', v')`` (Jacobian ``M - h D - h^2 K``,
    ``K = df/dx``, ``D = df/dv`` from ``system.force_jacobians``): ``newton="baraff_witkin"``
    takes only the linearised first step of [BW] Eq. (6), ``newton="full"`` iterates until
    ``|G| <= max(tol |G(v_k)|, atol)`` (``G`` in N·s).

    Parameters
    ----------
    system : object with ``mass`` ``(n,)`` (kg), ``force(x, v, t) -> (n, d)`` (N) and, for
        ``implicit_euler``, ``force_jacobians(x, v, t) -> (K, D)`` sparse ``(n*d, n*d)``
        (row-major flattening of ``(n, d)``). An optional ``fixed`` sequence of particle
        indices is pinned: those particles keep ``x0`` and zero velocity.
    x0, v0 : (n, d) initial positions (m) and velocities (m/s).
    dt : step (s) > 0.  n_steps : number of steps >= 0.
    newton : ``"full"`` or ``"baraff_witkin"`` (implicit Euler only).
    tol, atol : full Newton stops at ``|G| <= max(tol |G(v_k)|, atol)``; ``atol`` in N·s.
    max_iter : Newton iteration cap; not converging raises :class:`ConvergenceError`.
    solver : linear solver for ``M - h D - h^2 K``: ``"auto"``, ``"direct"``, ``"cg"``,
        ``"lagged"`` (see :class:`LinearSolver`), or a :class:`LinearSolver` instance.
    progress : tqdm progress bar.
    project : optional callable ``project(t_next, x, v)`` run after every step, before
        pinning; it may modify ``x`` and ``v`` (n, d) in place (kinematic rigs, contacts).
    save_every : store every ``save_every``-th state only (long runs, few frames).
    max_speed : optional speed bound (m/s): a state faster than it counts as a blow-up
        (callers that know their physical speed scale, e.g. a wave speed, catch blow-ups
        earlier).

    Returns
    -------
    SimulationResult with ``t``, ``x``, ``v`` (the stored states: ``n_steps // save_every + 1``);
    ``newton[k]`` residual norms of step ``k``.

    Raises
    ------
    ValueError / TypeError naming the argument for bad input (``n_steps`` above
    :data:`MAX_STEPS`, a stored trajectory above :data:`MAX_TRAJECTORY_BYTES`);
    :class:`SimulationDiverged` (naming the step, with the partial run) when the state stops
    being finite, exceeds ``max_speed``, or grows like a blow-up: a particle farther from its
    start than ``GROWTH_LIMIT · (L + |v0| τ + |a0| τ²/2)`` (``L`` the scene's extent,
    ``τ = t - t0``) whose displacement also grew more than ``GROWTH_RATIO``-fold since step
    ``2^j ∈ (k/4, k/2]`` — faster than any physical motion from this start;
    :class:`ConvergenceError` when Newton fails.
    """
    _check_method(method, MECHANICAL_METHODS)
    dt = _check_dt(dt)
    n_steps = _check_count(n_steps, "n_steps")
    if n_steps > MAX_STEPS:
        raise ValueError(f"n_steps = {n_steps:,} is more than the limit of {MAX_STEPS:,}; "
                         f"use a larger dt or a shorter run")
    if newton not in ("full", "baraff_witkin"):
        raise ValueError(f"unknown newton variant {newton!r}; valid: full, baraff_witkin")
    if isinstance(t0, (bool, np.bool_)) or not isinstance(t0, (int, float, np.integer,
                                                               np.floating)) \
            or not np.isfinite(t0):
        raise ValueError(f"t0 (start time) must be a finite number, got {t0!r}")
    t0 = float(t0)
    tol = _check_tolerance(tol, "tol")
    atol = _check_tolerance(atol, "atol")
    max_iter = _check_count(max_iter, "max_iter", lo=1)
    save_every = _check_count(save_every, "save_every", lo=1)
    if max_speed is not None:
        max_speed = _check_tolerance(max_speed, "max_speed")
        if max_speed == 0:
            raise ValueError("max_speed must be > 0 (or None for no speed bound), got 0")
    if project is not None and not callable(project):
        raise TypeError(f"project must be None or a function project(t, x, v), got "
                        f"{type(project).__name__}")
    for attr in ("mass", "force"):
        if not hasattr(system, attr):
            raise TypeError(f"system must have 'mass' and 'force' (like springs.SpringSystem); "
                            f"{type(system).__name__} has no {attr!r}")
    m = _as_state(system.mass, "system.mass").reshape(-1)
    x0 = _as_state(x0, "x0")
    v0 = _as_state(v0, "v0")
    if x0.ndim != 2 or x0.shape[0] != m.size or m.size == 0 or x0.shape[1] == 0:
        raise ValueError(f"x0 must have shape (n, d) with n = {m.size} particles (n >= 1, "
                         f"d >= 1), got {x0.shape}")
    if v0.shape != x0.shape:
        raise ValueError(f"v0 must have the same shape as x0 {x0.shape}, got {v0.shape}")
    _check_finite("x0", x0)
    _check_finite("v0", v0)
    n, d = x0.shape
    fixed = _fixed_indices(system, n)
    free = np.ones(n, bool)
    free[fixed] = False
    if not np.all(np.isfinite(m)) or np.any(m[free] <= 0):
        bad = int(np.flatnonzero(~np.isfinite(m) | (free & ~(m > 0)))[0])
        raise ValueError(f"system.mass must be finite and > 0 for free particles, particle "
                         f"{bad} has mass {m[bad]}")
    v0[fixed] = 0.0
    inv_m = np.zeros(n)
    inv_m[free] = 1.0 / m[free]  # pinned particles: infinite mass
    M_flat = np.repeat(m, d)
    pinned_dofs = (fixed[:, None] * d + np.arange(d)).reshape(-1)
    # Growth bound: how far a particle can get from the start at time τ with the initial
    # velocities and accelerations, R(τ) = L + |v0| τ + |a0| τ² / 2 (L: scene extent). A
    # blow-up grows exponentially and passes GROWTH_LIMIT · R within a few steps; motion
    # that is physical stays far below it (free fall follows R exactly). Forces that start
    # later (a drive, a stroke) may take a system past R, but then its displacement grows
    # like a power of time; a blow-up must also grow GROWTH_RATIO-fold since the step
    # 2^j in (k/4, k/2] (polynomial t^p motion: at most 4^p).
    with np.errstate(all="ignore"):
        a0 = np.asarray(system.force(x0, v0, t0), dtype=float)[free] * (1.0 / m[free])[:, None]
    L = max(float(np.ptp(x0, axis=0).max()) if n > 1 else 0.0, float(np.abs(x0).max()), 1e-3)
    v0_max = float(np.abs(v0).max())
    a0_max = float(np.abs(a0).max()) if a0.size and np.all(np.isfinite(a0)) else 0.0

    if method == "implicit_euler" and not isinstance(solver, LinearSolver):
        solver = LinearSolver(solver)
    n_saved = n_steps // save_every + 1
    _check_memory(2 * n_saved, n * d, "simulate",
                  f"store fewer states (save_every = {save_every} now), use a larger dt or a "
                  f"shorter run")
    t = t0 + dt * save_every * np.arange(n_saved)
    X = np.empty((n_saved, n, d))
    V = np.empty((n_saved, n, d))
    X[0], V[0] = x0, v0
    x, v, v_prev = x0, v0, None
    newton_hist = []
    marks = [(0, 0.0)]  # (step 0 or 2^j, largest displacement from x0 then)

    def force(x, v, tt):
        fo = np.asarray(system.force(x, v, tt), dtype=float)
        if fo.shape != (n, d):
            raise ValueError(f"system.force must return shape {(n, d)}, got {fo.shape}")
        return fo

    step = MECHANICAL_STEPS[method]  # the scheme, chosen once
    if method == "implicit_euler":
        def advance(x, v, v_prev, tk):
            return step(system, force, x, v, tk, dt, M_flat, pinned_dofs, newton=newton,
                        tol=tol, atol=atol, max_iter=max_iter, solver=solver,
                        dv_guess=None if v_prev is None else (v - v_prev).reshape(-1),
                        history=newton_hist)
    else:
        def advance(x, v, v_prev, tk):
            return step(force, inv_m, x, v, tk, dt)

    steps = range(n_steps)
    if progress:
        from tqdm.auto import tqdm

        steps = tqdm(steps, desc=method, leave=False)
    for k in steps:
        tk = t0 + k * dt
        with np.errstate(over="ignore", invalid="ignore"):
            xn, vn = advance(x, v, v_prev, tk)
            if project is not None:
                project(tk + dt, xn, vn)  # kinematic constraints, contacts: in place
            vn[fixed] = 0.0
            xn[fixed] = x0[fixed]
        tau = tk + dt - t0
        reach = GROWTH_LIMIT * (L + v0_max * tau + 0.5 * a0_max * tau**2)
        finite = bool(np.all(np.isfinite(xn)) and np.all(np.isfinite(vn)))
        moved = float(np.abs(xn - x0).max(initial=0.0)) if finite else np.inf
        if k + 1 == 2 * marks[-1][0] or k == 0:           # displacement at steps 1, 2, 4, 8 ...
            marks.append((k + 1, moved))
        ref_step, ref_moved = marks[-2]                   # the step 2^j in ((k+1)/4, (k+1)/2]
        grown = moved > reach and moved > GROWTH_RATIO * ref_moved
        fast = finite and max_speed is not None and float(np.abs(vn).max(initial=0.0)) > max_speed
        if not finite or grown or fast:
            kept = k // save_every + 1
            partial = SimulationResult(t[:kept].copy(), X[:kept].copy(), V[:kept].copy(),
                                       method, dt, newton_hist)
            if not finite:
                reason = "the state is no longer finite"
            elif grown:
                reason = (f"a particle moved {moved:.3g} from its start, more than "
                          f"{GROWTH_LIMIT:g}× what the initial velocities and forces allow "
                          f"({reach / GROWTH_LIMIT:.3g}), {moved / max(ref_moved, 1e-300):.3g}× "
                          f"farther than at step {ref_step}")
            else:
                reason = (f"a speed of {float(np.abs(vn).max()):.3g} exceeds max_speed = "
                          f"{max_speed:.3g}")
            raise SimulationDiverged(k + 1, tk, dt, method, partial, reason)
        v_prev, x, v = v, xn, vn
        if (k + 1) % save_every == 0:
            X[(k + 1) // save_every], V[(k + 1) // save_every] = x, v
    return SimulationResult(t, X, V, method, dt, newton_hist)


# ----------------------------------------------------------------------------------------
# analysis helpers used by the lessons


def stability_function(method: str, z):
    """Amplification factor ``R(z)`` with ``y_{k+1} = R(h λ) y_k`` on the test equation
    ``y' = λ y`` (complex ``z = h λ``). ``|R(z)| <= 1`` is the method's stability region.
    """
    _check_method(method, METHODS)
    z = np.asarray(z, dtype=complex)
    if method == "explicit_euler":
        return 1 + z
    if method in ("midpoint", "heun"):
        return 1 + z + z**2 / 2
    if method == "rk4":
        return 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24
    with np.errstate(divide="ignore", invalid="ignore"):
        if method == "implicit_euler":
            return 1 / (1 - z)
        return (1 + z / 2) / (1 - z / 2)


def convergence_order(dts, errors) -> float:
    """Least-squares slope of ``log(error)`` against ``log(dt)``: the measured order."""
    dts, errors = np.asarray(dts, float), np.asarray(errors, float)
    if dts.shape != errors.shape or dts.size < 2:
        raise ValueError("need at least two (dt, error) pairs of equal length")
    if np.any(dts <= 0) or np.any(errors <= 0):
        raise ValueError("dts and errors must be > 0 to take logarithms")
    return float(np.polyfit(np.log(dts), np.log(errors), 1)[0])
