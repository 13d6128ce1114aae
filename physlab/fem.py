"""2D Fixed Corotated linear-triangle FEM (PhysAnimator supplementary, Eqs. 1–7).

A body is a triangle mesh with rest positions ``X`` (n, 2), current positions ``x``
(n, 2) and triangles ``tris`` (T, 3). Per triangle (PhysAnimator supp. notation):

* deformation gradient, Eq. (6): ``F = [x1 - x0, x2 - x0] [X1 - X0, X2 - X0]^-1 = Ds Dm^-1``;
* Fixed Corotated energy density [Stomakhin et al. 2012], Eq. (5):
  ``Ψ(F) = μ |F - R|_F² + λ/2 (det F - 1)²`` with ``R`` the rotation of the polar
  decomposition of ``F``;
* first Piola–Kirchhoff stress, Eq. (5): ``P = ∂Ψ/∂F = 2μ (F - R) + λ (J - 1) J F^-T``
  (``J = det F``; ``J F^-T`` is the cofactor matrix, so no inverse is needed);
* elastic energy ``E = Σ_t Ψ(F_t) V_t`` and forces, Eq. (4): ``f = -∂E/∂x``; for one
  triangle ``[f1, f2] = -V P Dm^-T`` and ``f0 = -(f1 + f2)``;
* lumped masses, Eq. (3): ``m_i = Σ_{t ∋ i} ρ_t V_t / 3``.

In 2D, ``V_t`` is the triangle's rest area (unit thickness). Units are whatever the mesh
uses: for meshes built from images, lengths are pixels, so ``E`` and ``μ, λ`` are energy per
pixel² and forces are mass·px/s².

The polar rotation uses the closed form for 2×2 matrices: the rotation maximising
``tr(Rᵀ F)`` is ``R(θ)`` with ``θ = atan2(F10 - F01, F00 + F11)``. For ``det F > 0`` it is
the polar factor; for inverted triangles (``det F ≤ 0``) it is the rotation of the SVD
``U V^T`` with the sign of the smallest singular value flipped, which is exactly what makes
Fixed Corotated robust to inversion (Stomakhin et al. 2012, Sec. 4).

Everything is vectorised over triangles, with scatter by ``np.bincount``. :class:`CorotatedFEM`
precomputes the rest-shape data in a structure-of-arrays layout for repeated force
evaluations (the hot loop of :func:`physlab.physanimator.simulate`).
"""
from __future__ import annotations

import numpy as np

__all__ = [
    "lame_parameters", "rest_shape", "deformation_gradients", "polar_rotation",
    "fixed_corotated_energy_density", "fixed_corotated_stress", "fixed_corotated_stress_derivative",
    "elastic_energy", "elastic_forces", "elastic_stiffness", "lumped_masses", "CorotatedFEM",
    "stable_time_step",
]


def lame_parameters(E, nu, plane="strain"):
    """Lamé parameters ``(μ, λ)`` from Young's modulus ``E`` and Poisson ratio ``ν``.

    ``plane="strain"`` (default; as in PhysAnimator's and Taichi's 2D FEM):
    ``μ = E / (2 (1 + ν))``, ``λ = E ν / ((1 + ν)(1 - 2ν))``.
    ``plane="stress"`` (thin sheets): ``λ = E ν / (1 - ν²)``. Arrays broadcast.
    """
    if plane not in ("strain", "stress"):
        raise ValueError(f"plane must be 'strain' or 'stress', got {plane!r}")
    E = _numbers(E, "Young's modulus E")
    nu = _numbers(nu, "Poisson ratio nu")
    if not (np.all(np.isfinite(E)) and np.all(np.isfinite(nu))):
        raise ValueError(f"Young's modulus and Poisson ratio must be finite, got E = {E}, "
                         f"nu = {nu}")
    if np.any(E <= 0):
        raise ValueError(f"Young's modulus must be > 0, got {E}")
    if np.any(nu <= -1) or np.any(nu >= 0.5):
        raise ValueError(f"Poisson ratio must lie in (-1, 0.5), got {nu}")
    mu = E / (2 * (1 + nu))
    if plane == "strain":
        lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    else:
        lam = E * nu / (1 - nu**2)
    return (float(mu), float(lam)) if mu.ndim == 0 else (mu, lam)


def _numbers(value, name):
    """``value`` as a float array; TypeError naming ``name`` for non-numeric input."""
    if isinstance(value, (str, bytes)):
        raise TypeError(f"{name} must be a number or an array of numbers, got {value!r}")
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a number or an array of numbers, got "
                        f"{type(value).__name__}") from None


def _per_triangle(value, name, T, lo=None, lo_open=True):
    """Scalar or (T,) material parameter as a finite (T,) float array (> ``lo``, or >= ``lo``
    with ``lo_open=False``, if given)."""
    a = _numbers(value, name)
    if a.ndim and a.shape != (T,):
        raise ValueError(f"{name} must be a scalar or shape ({T},) (one per triangle), got "
                         f"shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {value!r:.80}")
    if lo is not None and np.any(a <= lo if lo_open else a < lo):
        raise ValueError(f"{name} must be {'>' if lo_open else '>='} {lo:g}, got min "
                         f"{float(a.min()):g}")
    return np.broadcast_to(a, (T,)).copy()


def _edge_matrices(P, tris):
    """``[P1 - P0, P2 - P0]`` as (T, 2, 2) with the edge vectors as columns."""
    p0 = P[tris[:, 0]]
    return np.stack([P[tris[:, 1]] - p0, P[tris[:, 2]] - p0], axis=2)


def _check_mesh(X, tris):
    X = _numbers(X, "X (rest positions)")
    tris = np.asarray(tris)
    if X.ndim != 2 or X.shape[1] != 2:
        raise ValueError(f"X must have shape (n, 2), got {X.shape}")
    if not np.all(np.isfinite(X)):
        bad = int(np.flatnonzero(~np.isfinite(X).all(1))[0])
        raise ValueError(f"X (rest positions) must be finite, vertex {bad} is {X[bad].tolist()}")
    if tris.ndim != 2 or tris.shape[1] != 3 or not np.issubdtype(tris.dtype, np.integer):
        raise ValueError(f"tris must be an int array of shape (T, 3), got {tris.dtype} {tris.shape}")
    if tris.size and (tris.min() < 0 or tris.max() >= len(X)):
        raise ValueError(f"tris refers to vertices outside 0..{len(X) - 1}")
    return X, tris


def rest_shape(X, tris):
    """Rest-shape data: ``Dm^-1`` (T, 2, 2) and rest areas ``V`` (T,) > 0.

    Raises ValueError for degenerate (zero-area) triangles, naming the first one."""
    X, tris = _check_mesh(X, tris)
    Dm = _edge_matrices(X, tris)
    det = Dm[:, 0, 0] * Dm[:, 1, 1] - Dm[:, 0, 1] * Dm[:, 1, 0]
    scale = max(np.ptp(X, axis=0).max(), 1e-300) if len(X) else 1.0
    bad = np.flatnonzero(np.abs(det) <= 1e-12 * scale**2)
    if bad.size:
        raise ValueError(f"{bad.size} degenerate (zero-area) triangle(s) in the rest mesh, first "
                         f"#{bad[0]} with vertices {tris[bad[0]].tolist()}; remove them or re-mesh")
    inv = np.empty_like(Dm)
    inv[:, 0, 0], inv[:, 1, 1] = Dm[:, 1, 1] / det, Dm[:, 0, 0] / det
    inv[:, 0, 1], inv[:, 1, 0] = -Dm[:, 0, 1] / det, -Dm[:, 1, 0] / det
    return inv, 0.5 * np.abs(det)


def deformation_gradients(x, X, tris, Dm_inv=None):
    """``F = Ds Dm^-1`` (T, 2, 2) — PhysAnimator supp. Eq. (6)."""
    x = np.asarray(x, dtype=float)
    if Dm_inv is None:
        Dm_inv, _ = rest_shape(X, tris)
    if x.shape != np.shape(X):
        raise ValueError(f"x must have the shape of X {np.shape(X)}, got {x.shape}")
    return _edge_matrices(x, np.asarray(tris)) @ Dm_inv  # Eq. (6)


def polar_rotation(F):
    """Rotation ``R`` (…, 2, 2) maximising ``tr(Rᵀ F)``: the polar factor of ``F``, robust
    to inversion (``det F ≤ 0`` gives a proper rotation too); ``R = I`` when ``F = 0``."""
    F = np.asarray(F, dtype=float)
    theta = np.arctan2(F[..., 1, 0] - F[..., 0, 1], F[..., 0, 0] + F[..., 1, 1])
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def _cofactor(F):
    """``J F^-T`` = cofactor matrix of 2×2 ``F``: [[F11, -F10], [-F01, F00]]."""
    C = np.empty_like(F)
    C[..., 0, 0], C[..., 0, 1] = F[..., 1, 1], -F[..., 1, 0]
    C[..., 1, 0], C[..., 1, 1] = -F[..., 0, 1], F[..., 0, 0]
    return C


def fixed_corotated_energy_density(F, mu, lam):
    """``Ψ(F) = μ |F - R|_F² + λ/2 (det F - 1)²`` (…,) — Eq. (5). ``mu``, ``lam`` broadcast."""
    F = np.asarray(F, dtype=float)
    R = polar_rotation(F)
    J = F[..., 0, 0] * F[..., 1, 1] - F[..., 0, 1] * F[..., 1, 0]
    return mu * np.sum((F - R) ** 2, axis=(-2, -1)) + 0.5 * lam * (J - 1) ** 2


def fixed_corotated_stress(F, mu, lam):
    """First Piola–Kirchhoff stress ``P = 2μ (F - R) + λ (J - 1) J F^-T`` (…, 2, 2) — Eq. (5)."""
    F = np.asarray(F, dtype=float)
    R = polar_rotation(F)
    J = F[..., 0, 0] * F[..., 1, 1] - F[..., 0, 1] * F[..., 1, 0]
    mu = np.asarray(mu, dtype=float)[..., None, None]
    lam = np.asarray(lam, dtype=float)[..., None, None]
    return 2 * mu * (F - R) + lam * (J - 1)[..., None, None] * _cofactor(F)  # Eq. (5)


def fixed_corotated_stress_derivative(F, mu, lam):
    """``dP/dF`` as (…, 2, 2, 2, 2) with ``dP[..., i, j, k, l] = ∂P_ij / ∂F_kl``.

    Beyond the paper (it uses explicit time stepping): needed by implicit Euler for stiff
    materials. In 2D the rotation is ``R(θ)`` with ``θ = atan2(B, A)``, ``A = F00 + F11``,
    ``B = F10 - F01``, so ``∂R/∂F = R'(θ) ⊗ ∂θ/∂F`` with ``∂θ = (A ∂B - B ∂A) / (A² + B²)``;
    the volume term differentiates the (linear) cofactor matrix.
    """
    F = np.asarray(F, dtype=float)
    R = polar_rotation(F)
    J = F[..., 0, 0] * F[..., 1, 1] - F[..., 0, 1] * F[..., 1, 0]
    C = _cofactor(F)
    shape = F.shape[:-2]
    mu = np.asarray(mu, dtype=float)
    lam = np.asarray(lam, dtype=float)
    a = F[..., 0, 0] + F[..., 1, 1]
    b = F[..., 1, 0] - F[..., 0, 1]
    q = a**2 + b**2
    q = np.where(q > 1e-300, q, 1e-300)
    # dθ/dF (…, 2, 2)
    dth = np.zeros(shape + (2, 2))
    dth[..., 0, 0] = -b / q
    dth[..., 1, 1] = -b / q
    dth[..., 1, 0] = a / q
    dth[..., 0, 1] = -a / q
    # dR/dθ = R · [[0, -1], [1, 0]]
    Rp = np.stack([np.stack([-R[..., 1, 0], -R[..., 0, 0]], -1),
                   np.stack([R[..., 0, 0], -R[..., 1, 0]], -1)], -2)
    eye4 = np.einsum("ik,jl->ijkl", np.eye(2), np.eye(2))
    dR = Rp[..., :, :, None, None] * dth[..., None, None, :, :]
    # d(J F^-T)/dF: cofactor is linear in F
    dC = np.zeros((2, 2, 2, 2))
    dC[0, 0, 1, 1] = dC[1, 1, 0, 0] = 1.0
    dC[0, 1, 1, 0] = dC[1, 0, 0, 1] = -1.0
    m = mu[..., None, None, None, None]
    lm = lam[..., None, None, None, None]
    return (2 * m * (eye4 - dR)
            + lm * C[..., :, :, None, None] * C[..., None, None, :, :]  # ∂J/∂F = C
            + lm * (J - 1)[..., None, None, None, None] * dC)


def elastic_energy(x, X, tris, mu, lam):
    """Total elastic energy ``E = Σ_t Ψ(F_t) V_t`` (float) — Eq. (4)."""
    Dm_inv, V = rest_shape(X, tris)
    F = deformation_gradients(x, X, tris, Dm_inv)
    return float(np.sum(fixed_corotated_energy_density(F, mu, lam) * V))


def _scatter_forces(tris, H, n):
    """Scatter per-triangle force columns ``H = [f1, f2]`` (T, 2, 2) into (n, 2) forces."""
    f = np.empty((n, 2))
    idx = np.concatenate([tris[:, 0], tris[:, 1], tris[:, 2]])
    for a in range(2):
        w = np.concatenate([-(H[:, a, 0] + H[:, a, 1]), H[:, a, 0], H[:, a, 1]])
        f[:, a] = np.bincount(idx, w, n)
    return f


def elastic_forces(x, X, tris, mu, lam):
    """Elastic forces ``f = -∂E/∂x`` (n, 2) — Eq. (4): ``[f1, f2] = -V P Dm^-T``, ``f0 = -f1 - f2``."""
    X, tris = _check_mesh(X, tris)
    Dm_inv, V = rest_shape(X, tris)
    F = deformation_gradients(x, X, tris, Dm_inv)
    P = fixed_corotated_stress(F, mu, lam)
    H = -V[:, None, None] * (P @ np.swapaxes(Dm_inv, 1, 2))  # Eq. (4)
    return _scatter_forces(tris, H, len(X))


def _shape_gradients(Dm_inv):
    """``B`` (T, 3, 2) with ``∂F_ij/∂x_{a,k} = δ_ik B[a, j]`` for the corners a = 0, 1, 2."""
    B = np.empty(Dm_inv.shape[:1] + (3, 2))
    B[:, 1:] = Dm_inv
    B[:, 0] = -(Dm_inv[:, 0] + Dm_inv[:, 1])
    return B


def elastic_stiffness(x, X, tris, mu, lam):
    """Stiffness matrix ``K = ∂f/∂x = -∂²E/∂x²`` as scipy CSR ``(2n, 2n)`` (row-major dofs).

    Beyond the paper (explicit there): lets implicit Euler take large steps on stiff
    materials. Per triangle ``K_{(a,i),(b,k)} = -V Σ_{j,l} B_aj ∂P_ij/∂F_kl B_bl``."""
    import scipy.sparse as sp

    X, tris = _check_mesh(X, tris)
    Dm_inv, V = rest_shape(X, tris)
    F = deformation_gradients(x, X, tris, Dm_inv)
    dP = fixed_corotated_stress_derivative(F, mu, lam)  # (T, 2, 2, 2, 2)
    B = _shape_gradients(Dm_inv)
    Kt = -V[:, None, None, None, None] * np.einsum("taj,tijkl,tbl->taibk", B, dP, B)  # (T,3,2,3,2)
    dof = 2 * tris[:, :, None] + np.arange(2)  # (T, 3, 2)
    rows = np.broadcast_to(dof[:, :, :, None, None], Kt.shape)
    cols = np.broadcast_to(dof[:, None, None, :, :], Kt.shape)
    n2 = 2 * len(X)
    return sp.csr_matrix((Kt.ravel(), (rows.ravel(), cols.ravel())), shape=(n2, n2))


def lumped_masses(X, tris, rho):
    """Lumped vertex masses ``m_i = Σ_{t ∋ i} ρ_t V_t / 3`` (n,) — Eq. (3), the diagonal of
    the mass matrix ``M`` of Eq. (2). ``rho`` scalar or (T,)."""
    X, tris = _check_mesh(X, tris)
    _, V = rest_shape(X, tris)
    rho = _per_triangle(rho, "density rho", len(V), lo=0)
    w = np.repeat(rho * V / 3.0, 3)  # Eq. (3)
    return np.bincount(tris.reshape(-1), w, len(X))


def stable_time_step(X, tris, E, nu, rho, safety=0.5):
    """CFL-like estimate of the largest stable explicit step (s): ``safety · h_min / c`` with
    ``h_min`` the smallest triangle height and ``c = sqrt((λ + 2μ)/ρ)`` the dilatational wave
    speed. Units follow the mesh (pixels → px/s). ``E``, ``nu``, ``rho`` scalars or (T,);
    ``safety`` in (0, 1]."""
    X, tris = _check_mesh(X, tris)
    if isinstance(safety, bool) or not isinstance(safety, (int, float, np.integer, np.floating)) \
            or not 0 < safety <= 1:
        raise ValueError(f"safety must be a number in (0, 1], got {safety!r}")
    T = len(tris)
    E = _per_triangle(E, "Young's modulus E", T, lo=0)
    rho = _per_triangle(rho, "density rho", T, lo=0)
    mu, lam = lame_parameters(np.max(E), nu)
    c = float(np.max(np.sqrt((lam + 2 * mu) / np.min(rho))))  # fastest wave speed
    _, V = rest_shape(X, tris)
    e = np.stack([X[tris[:, 1]] - X[tris[:, 0]], X[tris[:, 2]] - X[tris[:, 1]],
                  X[tris[:, 0]] - X[tris[:, 2]]], 1)
    longest = np.linalg.norm(e, axis=2).max(1)
    h_min = float(np.min(2 * V / longest))
    return safety * h_min / c


class CorotatedFEM:
    """Precomputed Fixed Corotated FEM for one mesh: fast repeated ``forces(x)``.

    Structure of arrays: the four entries of ``Dm^-1``, ``V``, and the per-triangle
    ``μ V``, ``λ V`` are stored as flat (T,) arrays; ``forces`` evaluates Eqs. (4–6) with
    closed-form 2×2 arithmetic and two ``np.bincount`` scatters.

    Parameters
    ----------
    X : (n, 2) rest positions.  tris : (T, 3) int.  mu, lam : scalars or (T,).
    """

    def __init__(self, X, tris, mu, lam):
        X, tris = _check_mesh(X, tris)
        Dm_inv, V = rest_shape(X, tris)
        self.X, self.tris, self.n = X, tris.astype(np.intp), len(X)
        self.V = V
        self.mu = _per_triangle(mu, "mu (Lamé μ)", len(V), lo=0, lo_open=False)
        self.lam = _per_triangle(lam, "lam (Lamé λ)", len(V))
        self._B = [np.ascontiguousarray(Dm_inv[:, i, j]) for i in range(2) for j in range(2)]
        self._muV = 2 * self.mu * V
        self._lamV = self.lam * V
        self._i0, self._i1, self._i2 = (np.ascontiguousarray(self.tris[:, k]) for k in range(3))
        self._idx = np.concatenate([self._i0, self._i1, self._i2])

    def stiffness(self, x):
        """``K = ∂f/∂x`` (2n, 2n) CSR — see :func:`elastic_stiffness`."""
        return elastic_stiffness(x, self.X, self.tris, self.mu, self.lam)

    def deformation_gradients(self, x):
        """(T, 2, 2) ``F`` — Eq. (6)."""
        return deformation_gradients(x, self.X, self.tris, self.Dm_inv)

    @property
    def Dm_inv(self):
        b00, b01, b10, b11 = self._B
        return np.stack([np.stack([b00, b01], -1), np.stack([b10, b11], -1)], -2)

    def _F(self, x):
        x0, y0 = x[self._i0, 0], x[self._i0, 1]
        e1x, e1y = x[self._i1, 0] - x0, x[self._i1, 1] - y0
        e2x, e2y = x[self._i2, 0] - x0, x[self._i2, 1] - y0
        b00, b01, b10, b11 = self._B
        return (e1x * b00 + e2x * b10, e1x * b01 + e2x * b11,
                e1y * b00 + e2y * b10, e1y * b01 + e2y * b11)  # Eq. (6), row-major F

    def energy(self, x):
        """Total elastic energy (float)."""
        a, b, c, d = self._F(np.asarray(x, dtype=float))
        th = np.arctan2(c - b, a + d)
        cs, sn = np.cos(th), np.sin(th)
        J = a * d - b * c
        psi = 0.5 * self._muV * ((a - cs) ** 2 + (b + sn) ** 2 + (c - sn) ** 2 + (d - cs) ** 2)
        return float(np.sum(psi + 0.5 * self._lamV * (J - 1) ** 2))

    def forces(self, x):
        """Elastic forces ``-∂E/∂x`` (n, 2) — Eqs. (4–6), structure-of-arrays closed forms.

        Same result as :func:`elastic_forces` (the readable reference); this version works in
        preallocated (T,) buffers with in-place ufuncs, because on large meshes allocating
        fresh temporaries (page faults) costs more than the arithmetic itself."""
        x = np.asarray(x, dtype=float)
        if x.shape != (self.n, 2):
            raise ValueError(f"x must have shape ({self.n}, 2), got {x.shape}")
        w = self._buffers()
        a, b, c, d, t, r = w["a"], w["b"], w["c"], w["d"], w["t"], w["r"]
        p00, p01, p10, p11 = w["p00"], w["p01"], w["p10"], w["p11"]
        b00, b01, b10, b11 = self._B
        # edge vectors e1 = x1 - x0, e2 = x2 - x0 (stored in the p buffers for now)
        e1x, e1y, e2x, e2y = p00, p01, p10, p11
        np.copyto(w["xs"], x[:, 0])  # contiguous columns gather faster
        np.copyto(w["ys"], x[:, 1])
        for col, e1, e2 in ((w["xs"], e1x, e2x), (w["ys"], e1y, e2y)):
            np.take(col, self._i0, out=t)
            np.take(col, self._i1, out=e1)
            np.take(col, self._i2, out=e2)
            e1 -= t
            e2 -= t
        # F = Ds Dm^-1 (Eq. 6): rows (e1x, e2x) and (e1y, e2y) times Dm^-1
        for out, u, v, bu, bv in ((a, e1x, e2x, b00, b10), (b, e1x, e2x, b01, b11),
                                  (c, e1y, e2y, b00, b10), (d, e1y, e2y, b01, b11)):
            np.multiply(u, bu, out=out)
            np.multiply(v, bv, out=t)
            out += t
        # polar rotation R = [[cs, -sn], [sn, cs]], cs = (a + d)/r, sn = (c - b)/r; R = I if r = 0
        cs, sn, g, z = w["cs"], w["sn"], w["g"], w["z"]
        np.add(a, d, out=cs)
        np.subtract(c, b, out=sn)
        np.multiply(cs, cs, out=r)  # r = sqrt(cs² + sn²): 10× cheaper than np.hypot, exact
        np.multiply(sn, sn, out=t)  # unless |F| entries are below ~1e-154
        r += t
        np.sqrt(r, out=r)
        np.equal(r, 0.0, out=z)
        r += z
        cs += z
        cs /= r
        sn /= r
        # g = λV (J - 1); V·P = 2μV (F - R) + g cof(F), cof(F) = [[d, -c], [-b, a]] (Eq. 5)
        np.multiply(a, d, out=g)
        np.multiply(b, c, out=t)
        g -= t
        g -= 1.0
        g *= self._lamV
        m = self._muV
        for out, f_ij, rot, sign_r, cof, sign_c in ((p00, a, cs, -1, d, 1), (p01, b, sn, 1, c, -1),
                                                    (p10, c, sn, -1, b, -1), (p11, d, cs, -1, a, 1)):
            if sign_r > 0:
                np.add(f_ij, rot, out=out)
            else:
                np.subtract(f_ij, rot, out=out)
            out *= m
            np.multiply(g, cof, out=t)
            if sign_c > 0:
                out += t
            else:
                out -= t
        # [f1, f2] = -(V P) Dm^-T (Eq. 4); f0 = -(f1 + f2); scatter with bincount
        T = len(t)
        f = np.empty((self.n, 2))
        for k, (pa, pb) in enumerate(((p00, p01), (p10, p11))):
            W = w["w"]
            f0, f1, f2 = W[:T], W[T:2 * T], W[2 * T:]
            np.multiply(pa, b00, out=f1)
            np.multiply(pb, b01, out=t)
            f1 += t
            np.multiply(pa, b10, out=f2)
            np.multiply(pb, b11, out=t)
            f2 += t
            np.add(f1, f2, out=f0)  # f0 = -(f1 + f2) with f1, f2 still of the wrong sign
            f1 *= -1.0
            f2 *= -1.0
            f[:, k] = np.bincount(self._idx, W, self.n)
        return f

    def _buffers(self):
        """Work arrays, allocated once per model."""
        if getattr(self, "_work", None) is None:
            T = len(self.V)
            self._work = {k: np.empty(T) for k in ("a", "b", "c", "d", "t", "r", "cs", "sn", "g",
                                                   "p00", "p01", "p10", "p11")}
            self._work["z"] = np.empty(T)
            self._work["w"] = np.empty(3 * T)
            self._work["xs"] = np.empty(self.n)
            self._work["ys"] = np.empty(self.n)
        return self._work
