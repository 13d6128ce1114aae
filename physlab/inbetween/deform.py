"""Skeleton-driven deformation by the symmetric Dirichlet energy (Brodt & Bessmeltsev 2024, Sec. 4.3).

For a template with rest vertices ``X`` and deformed vertices ``x`` the paper minimises
(Eq. 1, fixed topology)

    E(x) = E_d(x) + E_pose(x),
    E_d(x) = Σ_f A_f (‖J_f‖_F² + ‖J_f⁻¹‖_F²),      Σ_f A_f = 1,
    E_pose(x) = μ/2 Σ_k ‖B_k x − x̂_k‖²,             μ = 200,

where ``J_f = Ds Dm⁻¹`` is the 2×2 Jacobian of triangle f's affine map (the deformation
gradient ``F`` of :mod:`physlab.fem`), ``B_k x`` the position of handle k (a joint or a bone
midpoint) and ``x̂_k`` its target. ``‖J‖² + ‖J⁻¹‖² ≥ 4`` with equality exactly for rotations,
so ``E_d ≥ 4`` and ``E_d = 4`` for rigid motions; it blows up as a triangle degenerates, so
minimisers never fold (local injectivity).

Units. ``E_d`` is scale-free (Jacobians are dimensionless, areas sum to 1); ``E_pose`` is in
pixels², so with μ = 200 a handle 1 px off costs 100 — 25× the energy of the undeformed
template — and handles land well within a pixel of their targets. (``length_scale`` divides
all coordinates first; a value of the image size would make μ = 200 a soft constraint with
errors of tens of pixels on large bends.) The stopping test uses the *Sobolev* norm of the
gradient, ``‖∇E‖_P⁻¹ = sqrt(∇Eᵀ P⁻¹ ∇E)``: ``½‖∇E‖²_P⁻¹`` estimates the energy still to be
gained, so the paper's threshold 0.01 means the same at any resolution and mesh size (the
Euclidean norm of ``∇E_d`` shrinks with the triangle size and would stop far too early).

Solver (Sec. 4.3 "Continuous optimization"): a Sobolev (H¹) preconditioned gradient method
[Kovalsky et al. 2016]. The search direction is ``d = −P⁻¹ ∇E`` with

    P = 4 L / Σ_f A_f^rest + μ BᵀB,

``L`` the cotangent Laplacian (positive semi-definite, null space = translations), i.e. the
Hessian of ``E_d`` at the rest state in the directions that stretch (the factor 4 bounds the
symmetric Dirichlet Hessian at J = I) plus the exact Hessian of ``E_pose``. The paper factors
``L`` and projects its translation null space out; adding ``μBᵀB`` (positive definite on
translations as soon as one handle exists) removes the null space *and* lets the handles'
pull move the whole mesh in one step. ``P`` depends only on the rest mesh, so it is
factored once (sparse LU, the stand-in for CHOLMOD) and reused for every iteration and frame.
The step length comes from a line search with the Armijo and (weak) Wolfe conditions,
``c1 = 1e-4``, ``c2 = 0.9`` [Nocedal & Wright 1999], started at
``min(1, 0.9 α_max)`` where ``α_max`` is the largest step before any triangle flips
[Smith & Schaefer 2015]: the root of ``det(Ds + α dDs) = 0``, a quadratic in α per triangle.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import splu

from ..fem import _edge_matrices, rest_shape
from .skeleton import Skeleton

__all__ = ["symmetric_dirichlet_energy", "symmetric_dirichlet_gradient",
           "symmetric_dirichlet_density", "max_injective_step", "cotangent_laplacian",
           "SymmetricDirichletDeformer", "DeformResult", "deform", "flipped_count",
           "MU", "TOL", "MAX_ITER"]

MU = 200.0        #: pose weight μ (paper Sec. 4.3)
TOL = 0.01        #: stop when the Sobolev gradient norm ‖∇E‖_P⁻¹ < TOL (paper Sec. 4.3: 0.01)
MAX_ITER = 5000   #: iteration cap (paper Sec. 4.3)
C1, C2 = 1e-4, 0.9  #: Armijo / Wolfe constants [Nocedal & Wright]


def _inv_and_det(M):
    det = M[:, 0, 0] * M[:, 1, 1] - M[:, 0, 1] * M[:, 1, 0]
    inv = np.empty_like(M)
    inv[:, 0, 0], inv[:, 1, 1] = M[:, 1, 1], M[:, 0, 0]
    inv[:, 0, 1], inv[:, 1, 0] = -M[:, 0, 1], -M[:, 1, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv /= det[:, None, None]
    return inv, det


def symmetric_dirichlet_density(J):
    """``‖J‖_F² + ‖J⁻¹‖_F²`` (T,) per 2×2 Jacobian (T, 2, 2); +inf where det J ≤ 0."""
    J = np.asarray(J, dtype=float)
    Jinv, det = _inv_and_det(J)
    with np.errstate(invalid="ignore"):
        out = np.sum(J * J, axis=(1, 2)) + np.sum(Jinv * Jinv, axis=(1, 2))
    return np.where(det > 0, out, np.inf)


def _normalised_areas(X, tris):
    Dm_inv, area = rest_shape(X, tris)
    return Dm_inv, area / area.sum()


def symmetric_dirichlet_energy(X, tris, x):
    """Symmetric Dirichlet energy ``E_d = Σ_f A_f (‖J_f‖² + ‖J_f⁻¹‖²)``, ``Σ A_f = 1``.

    Brodt & Bessmeltsev 2024 Eq. (1). ``X``, ``x`` (n, 2), ``tris`` (T, 3) int.
    Returns a float ≥ 4 (= 4 for rigid motions), +inf if a triangle is flipped or degenerate.
    """
    Dm_inv, A = _normalised_areas(X, tris)
    J = _edge_matrices(np.asarray(x, dtype=float), np.asarray(tris)) @ Dm_inv
    return float(np.sum(A * symmetric_dirichlet_density(J)))


def _sd_energy_grad(x, tris, Dm_inv, A, n):
    """E_d and ∂E_d/∂x (n, 2) for non-flipped x (caller checks finiteness); ``(inf, None)``
    if a triangle is flipped or degenerate.

    Written out per 2×2 entry, because the solver calls it thousands of times on a few hundred
    triangles, where NumPy's stacked 2×2 products cost more than the arithmetic. With
    ``J = [[a, b], [c, d]] = Ds Dm⁻¹``, ``s = ‖J‖²`` and ``δ = det J``: ``‖J⁻¹‖² = s / δ²``, so
    ``ψ = s (1 + 1/δ²)`` and ``∂ψ/∂J = 2 (1 + 1/δ²) J − (2 s / δ³) cof J`` with
    ``cof J = [[d, −c], [−b, a]]`` (the same as ``2J − 2 J⁻ᵀ J⁻¹ J⁻ᵀ``); then
    ``∂E/∂[e1 e2] = A ∂ψ/∂J Dm⁻ᵀ``, spread to the three vertices (e_k = x_k − x_0)."""
    p0 = x[tris[:, 0]]
    e1 = x[tris[:, 1]] - p0                                       # (T, 2) columns of Ds
    e2 = x[tris[:, 2]] - p0
    m00, m01 = Dm_inv[:, 0, 0], Dm_inv[:, 0, 1]
    m10, m11 = Dm_inv[:, 1, 0], Dm_inv[:, 1, 1]
    a = e1[:, 0] * m00 + e2[:, 0] * m10
    b = e1[:, 0] * m01 + e2[:, 0] * m11
    c = e1[:, 1] * m00 + e2[:, 1] * m10
    d = e1[:, 1] * m01 + e2[:, 1] * m11
    det = a * d - b * c
    if not np.all(det > 0):
        return np.inf, None
    s = a * a + b * b + c * c + d * d
    inv2 = 1.0 / (det * det)
    e = float(np.dot(A, s * (1.0 + inv2)))
    k1 = 2.0 * (1.0 + inv2) * A
    k2 = 2.0 * s * inv2 / det * A
    g00, g01 = k1 * a - k2 * d, k1 * b + k2 * c                   # A ∂ψ/∂J
    g10, g11 = k1 * c + k2 * b, k1 * d - k2 * a
    h1x, h2x = g00 * m00 + g01 * m01, g00 * m10 + g01 * m11       # · Dm⁻ᵀ
    h1y, h2y = g10 * m00 + g11 * m01, g10 * m10 + g11 * m11
    g = np.empty((n, 2))
    idx = tris.T.ravel()                                          # vertex 0s, 1s, 2s
    g[:, 0] = np.bincount(idx, np.concatenate([-(h1x + h2x), h1x, h2x]), n)
    g[:, 1] = np.bincount(idx, np.concatenate([-(h1y + h2y), h1y, h2y]), n)
    return e, g


def symmetric_dirichlet_gradient(X, tris, x):
    """``∂E_d/∂x`` (n, 2) of :func:`symmetric_dirichlet_energy`.

    Per triangle ``∂ψ/∂J = 2J − 2 J⁻ᵀ J⁻¹ J⁻ᵀ``, chained through ``J = Ds Dm⁻¹``. Raises
    ValueError if a triangle of ``x`` is flipped (the energy is infinite there).
    """
    X = np.asarray(X, dtype=float)
    tris = np.asarray(tris)
    Dm_inv, A = _normalised_areas(X, tris)
    e, g = _sd_energy_grad(np.asarray(x, dtype=float), tris, Dm_inv, A, len(X))
    if g is None:
        raise ValueError("x has flipped or degenerate triangles: the energy is infinite there")
    return g


def max_injective_step(x, d, tris):
    """Largest ``α`` such that no triangle of ``x + α' d`` flips for ``0 ≤ α' < α``.

    Smith & Schaefer 2015: ``det(Ds + α dDs) = a α² + b α + c`` per triangle; the smallest
    positive root over all triangles (``inf`` if there is none). ``x``, ``d`` (n, 2).
    """
    A = _edge_matrices(np.asarray(x, dtype=float), tris)
    D = _edge_matrices(np.asarray(d, dtype=float), tris)
    a = D[:, 0, 0] * D[:, 1, 1] - D[:, 0, 1] * D[:, 1, 0]
    b = A[:, 0, 0] * D[:, 1, 1] + A[:, 1, 1] * D[:, 0, 0] - A[:, 0, 1] * D[:, 1, 0] \
        - A[:, 1, 0] * D[:, 0, 1]
    c = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
    roots = np.full(len(a), np.inf)
    lin = np.abs(a) <= 1e-14 * (np.abs(b) * np.abs(c) ** 0.5 + np.abs(c) + 1e-300)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = -c[lin] / b[lin]
        roots[lin] = np.where(r > 0, r, np.inf)
        q = ~lin
        disc = b[q] ** 2 - 4 * a[q] * c[q]
        sq = np.sqrt(np.maximum(disc, 0.0))
        # numerically stable pair of roots
        t = -0.5 * (b[q] + np.copysign(sq, b[q]))
        r1, r2 = t / a[q], c[q] / t
        r1 = np.where((disc >= 0) & (r1 > 0), r1, np.inf)
        r2 = np.where((disc >= 0) & (r2 > 0), r2, np.inf)
        roots[q] = np.minimum(r1, r2)
    return float(np.min(roots)) if len(roots) else np.inf


def flipped_count(X, x, tris):
    """Number of triangles whose signed area in ``x`` is 0 or has the opposite sign to ``X``:
    ``len(flipped_triangles(X, x, tris, rtol=0))`` (:func:`physlab.inbetween.skinning.
    flipped_triangles`, the one place that decides what a flipped triangle is)."""
    from .skinning import flipped_triangles

    return int(len(flipped_triangles(X, x, tris, rtol=0.0)))


def cotangent_laplacian(X, tris):
    """Positive semi-definite cotangent Laplacian ``L`` (n, n) sparse [Pinkall & Polthier 1993].

    ``xᵀ L x = Σ_f a_f ‖∇x‖²`` (Dirichlet energy with the *unnormalised* rest areas ``a_f``);
    computed by :func:`igl.cotmatrix` (which returns ``−L``).
    """
    import igl

    return sparse.csr_matrix(-igl.cotmatrix(np.asarray(X, dtype=np.float64),
                                            np.asarray(tris, dtype=np.int64)))


@dataclass
class DeformResult:
    """Outcome of :meth:`SymmetricDirichletDeformer.solve`.

    Attributes
    ----------
    x : (n, 2) deformed vertices in pixels.
    energy : float, final E = E_d + E_pose.
    energy_d : float, final E_d (4 = rigid).
    iterations : int.
    converged : bool, ‖∇E‖_P⁻¹ < tol was reached.
    handle_error : (K,) px, distance of each handle from its target.
    history : dict of lists "energy", "grad_norm" (Sobolev norm), "step" (per iteration, if recorded).
    """

    x: np.ndarray
    energy: float
    energy_d: float
    iterations: int
    converged: bool
    handle_error: np.ndarray
    history: dict = field(default_factory=dict)


class SymmetricDirichletDeformer:
    """Minimiser of ``E_d + E_pose`` for one template (factorisation reused across frames).

    Parameters
    ----------
    X : (n, 2) rest vertices in pixels, or a :class:`~physlab.inbetween.template.Template`
        (then ``tris`` and ``B`` are taken from it).
    tris : (T, 3) int triangles.
    B : sparse (K, n) handle matrix (``Template.handle_matrix()``).
    mu : float, pose weight μ (paper: 200).
    length_scale : float px, coordinates are divided by it (default 1: pixels).
    preconditioner : "sobolev" (default, see the module docstring) or "none" (plain
        gradient descent, for comparison).
    """

    def __init__(self, X, tris=None, B=None, mu=MU, length_scale=None, preconditioner="sobolev"):
        from .template import Template

        if isinstance(X, Template):
            t = X
            X, tris, B = t.mesh.X, t.mesh.tris, t.handle_matrix()
        X = np.asarray(X, dtype=float)
        if tris is None or B is None:
            raise ValueError("pass a Template, or X together with tris and the handle matrix B")
        tris = np.asarray(tris, dtype=np.int64)
        B = sparse.csr_matrix(B)
        if B.shape[1] != len(X) or B.shape[0] == 0:
            raise ValueError(f"B must have shape (K >= 1, {len(X)}), got {B.shape}")
        if mu <= 0:
            raise ValueError(f"mu must be > 0, got {mu}")
        if preconditioner not in ("sobolev", "none"):
            raise ValueError(f"preconditioner must be 'sobolev' or 'none', got {preconditioner!r}")
        self.scale = 1.0 if length_scale is None else float(length_scale)
        if not self.scale > 0:
            raise ValueError(f"length_scale must be > 0, got {length_scale}")
        self.X, self.tris, self.B, self.mu = X, tris, B, float(mu)
        self._Bt = B.T          # made once: scipy builds a new matrix on every B.T
        self.n = len(X)
        self.Xs = X / self.scale
        self.Dm_inv, self.A = _normalised_areas(self.Xs, tris)
        self.preconditioner = preconditioner
        # P is factored for both choices: it also defines the stopping norm ‖∇E‖_P⁻¹
        area = rest_shape(self.Xs, tris)[1].sum()
        P = 4.0 * cotangent_laplacian(self.Xs, tris) / area + self.mu * (B.T @ B)
        self._lu = splu(sparse.csc_matrix(P), permc_spec="MMD_AT_PLUS_A")

    # ---------------------------------------------------------------- energy
    def _energy_grad(self, xs, targets_s):
        ed, g = _sd_energy_grad(xs, self.tris, self.Dm_inv, self.A, self.n)
        if g is None:
            return np.inf, np.inf, None
        r = self.B @ xs - targets_s
        e = ed + 0.5 * self.mu * float(np.sum(r * r))   # Eq. (1): E_d + E_pose
        g += self.mu * (self._Bt @ r)
        return e, ed, g

    def energy(self, x, targets):
        """``E_d + E_pose`` (float) at pixel positions ``x`` (n, 2) for handle targets (K, 2)."""
        return self._energy_grad(np.asarray(x, float) / self.scale,
                                 np.asarray(targets, float) / self.scale)[0]

    def _direction(self, g, memory=()):
        """(search direction, Sobolev gradient norm ‖g‖_P⁻¹).

        With ``memory`` (pairs ``(s, y, ρ)`` of the last steps, oldest first) the direction
        is the L-BFGS two-loop recursion with initial inverse Hessian ``H0 = γ P⁻¹``
        (Sobolev metric; ``γ = sᵀy / yᵀP⁻¹y`` of the newest pair) or ``γ I`` without
        preconditioner [Nocedal & Wright, Alg. 7.4].
        """
        pg = self._lu.solve(g)
        sob = float(np.sqrt(max(np.sum(g * pg), 0.0)))
        H0 = self._lu.solve if self.preconditioner == "sobolev" else (lambda v: v)
        if not memory:
            return -(pg if self.preconditioner == "sobolev" else g), sob
        q = g.copy()
        alphas = []
        for s_, y_, rho in reversed(memory):
            a = rho * float(np.sum(s_ * q))
            q -= a * y_
            alphas.append(a)
        s_, y_, _ = memory[-1]
        Hy = H0(y_)
        r = (float(np.sum(s_ * y_)) / float(np.sum(y_ * Hy))) * H0(q)
        for (s_, y_, rho), a in zip(memory, reversed(alphas)):
            b = rho * float(np.sum(y_ * r))
            r += (a - b) * s_
        return -r, sob

    # ---------------------------------------------------------------- solve
    def solve(self, targets, x0=None, tol=TOL, max_iter=MAX_ITER, method="lbfgs", memory=8,
              record=False):
        """Deform towards handle ``targets`` (K, 2) px (or a posed Skeleton's handles).

        Parameters
        ----------
        targets : (K, 2) pixels, or a Skeleton (its :meth:`~Skeleton.handles`).
        x0 : (n, 2) starting vertices (pixels, must not be flipped); default the rest mesh.
            Warm-start successive frames from the previous solution.
        tol : float, stop when the Sobolev gradient norm ‖∇E‖_P⁻¹ < tol.
        max_iter : int.
        method : "lbfgs" (default: the paper's Laplacian-preconditioned quasi-Newton method,
            L-BFGS with the Sobolev metric as initial inverse Hessian) or "gradient" (the
            plain (Sobolev) gradient method: ``d = −P⁻¹∇E``).
        memory : int ≥ 1, L-BFGS memory (pairs kept).
        record : bool, keep per-iteration energy, gradient norm and step.

        Returns
        -------
        DeformResult.
        """
        if method not in ("lbfgs", "gradient"):
            raise ValueError(f"method must be 'lbfgs' or 'gradient', got {method!r}")
        if isinstance(targets, Skeleton):
            targets = targets.handles()
        targets = np.asarray(targets, dtype=float)
        if targets.shape != (self.B.shape[0], 2):
            raise ValueError(f"targets must have shape ({self.B.shape[0]}, 2) (one per handle), "
                             f"got {targets.shape}")
        if not np.all(np.isfinite(targets)):
            raise ValueError("targets contain NaN or inf")
        xs = (self.X if x0 is None else np.asarray(x0, dtype=float)) / self.scale
        if xs.shape != (self.n, 2):
            raise ValueError(f"x0 must have shape ({self.n}, 2), got {xs.shape}")
        ts = targets / self.scale
        e, ed, g = self._energy_grad(xs, ts)
        if g is None:
            raise ValueError("x0 has flipped or degenerate triangles; start from an injective "
                             "mesh (e.g. the rest mesh)")
        d, sob = self._direction(g)
        mem = []
        hist = {"energy": [e], "grad_norm": [sob], "step": []}
        converged = False
        it = 0
        for it in range(1, max_iter + 1):
            if sob < tol:
                converged, it = True, it - 1
                break
            slope = float(np.sum(g * d))
            if slope >= 0:  # not a descent direction (numerical breakdown): restart
                mem.clear()
                d, _ = self._direction(g)
                slope = float(np.sum(g * d))
            amax = max_injective_step(xs, d, self.tris)
            a = min(1.0, 0.9 * amax)
            lo, hi = 0.0, np.inf
            accepted = None
            for _ in range(40):
                xn = xs + a * d
                en, edn, gnw = self._energy_grad(xn, ts)
                if not np.isfinite(en) or en > e + C1 * a * slope:      # Armijo fails
                    hi = a
                    a = 0.5 * (lo + hi)
                elif float(np.sum(gnw * d)) < C2 * slope and a < 0.9 * amax * 0.999 \
                        and hi == np.inf:                                # Wolfe fails: go further
                    lo = a
                    accepted = (a, xn, en, edn, gnw)
                    a = min(2.0 * a, 0.9 * amax)
                else:
                    accepted = (a, xn, en, edn, gnw)
                    break
            if accepted is None:  # no decrease possible at machine precision
                break
            a, x_new, e_new, ed, g_new = accepted
            stalled = abs(e - e_new) <= 1e-15 * max(1.0, abs(e))
            if method == "lbfgs":
                s_, y_ = x_new - xs, g_new - g
                sy = float(np.sum(s_ * y_))
                if sy > 1e-12 * float(np.sqrt(np.sum(s_ * s_) * np.sum(y_ * y_))):
                    mem.append((s_, y_, 1.0 / sy))
                    del mem[:-memory]
            xs, e, g = x_new, e_new, g_new
            d, sob = self._direction(g, mem)
            if record:
                hist["energy"].append(e)
                hist["grad_norm"].append(sob)
                hist["step"].append(a)
            if stalled:
                break
        else:
            it = max_iter
        x = xs * self.scale
        err = np.linalg.norm(self.B @ x - targets, axis=1)
        if not record:
            hist = {}
        return DeformResult(x=x, energy=e, energy_d=ed, iterations=it, converged=converged,
                            handle_error=err, history=hist)


def deform(template, targets, x0=None, **options):
    """Deform a template so its handles reach ``targets`` (DESIGN API).

    Parameters
    ----------
    template : Template.
    targets : (K, 2) handle targets in pixels, or a posed Skeleton with the template's
        topology (checked).
    x0 : (n, 2) warm start (pixels) or None (rest mesh).
    **options : ``mu``, ``preconditioner`` (deformer) and ``tol``, ``max_iter`` (solve).

    Returns
    -------
    (n, 2) deformed vertex positions in pixels.
    """
    if isinstance(targets, Skeleton):
        targets = template.targets(targets)
    ctor = {k: options.pop(k) for k in ("mu", "preconditioner", "length_scale") if k in options}
    return SymmetricDirichletDeformer(template, **ctor).solve(targets, x0=x0, **options).x


#: largest handle move (px) between two solves of a sequence; bigger frame-to-frame moves are
#: split into sub-steps along the skeletal interpolation (continuation)
MAX_HANDLE_STEP = 16.0


def substeps(prev, skel, max_step):
    """Skeletons from ``prev`` (exclusive) to ``skel`` (inclusive) with no handle moving more
    than ``max_step`` px from one to the next (:func:`~physlab.inbetween.skeleton.interpolate`):
    the continuation path of :func:`deform_through`, each solve warm-started from the last."""
    from .skeleton import interpolate

    move = np.linalg.norm(skel.handles() - prev.handles(), axis=1).max()
    k = max(1, int(np.ceil(move / max_step)))
    return interpolate(prev, skel, np.arange(1, k + 1) / k) if k > 1 else [skel]


def deform_through(deformer, skeletons, x0=None, start=None, max_handle_step=MAX_HANDLE_STEP,
                   **solve):
    """Deform through a sequence of poses, each solve warm-started from the previous one.

    Large rotations reached in one solve can get stuck in distorted local minima (the pose
    term, μ = 200 per px², pulls handles far ahead of the mesh), so a move of more than
    ``max_handle_step`` px from the last pose (``start``, default: the first skeleton itself)
    goes through intermediate poses (:func:`substeps`).

    Parameters
    ----------
    deformer : SymmetricDirichletDeformer.
    skeletons : list of posed Skeletons (the template's topology).
    x0 : (n, 2) start vertices (default the rest mesh), ``start`` the Skeleton they are posed at.
    solve : options of :meth:`SymmetricDirichletDeformer.solve`.

    Returns
    -------
    DeformResult of the last pose.
    """
    x, prev, res = x0, start, None
    for s in skeletons:
        for q in ([s] if prev is None else substeps(prev, s, max_handle_step)):
            res = deformer.solve(q.handles(), x0=x, **solve)
            x = res.x
        prev = s
    return res
