"""Mass-spring systems: forces, energy, sparse force Jacobians and scene builders.

A :class:`SpringSystem` is a set of particles (positions ``x`` ``(n, d)``, ``d`` = 2 or 3,
masses ``m`` ``(n,)``) joined by Hooke springs, with viscous damping, gravity and, when
asked, a penalty ground plane. It offers exactly what :func:`physlab.integrators.simulate`
needs: ``mass``, ``force(x, v, t)``, ``force_jacobians(x, v, t)`` and ``fixed``.

Forces on particle ``i`` of a spring ``(i, j)`` with rest length ``L``, ``u = x_j - x_i``,
``l = |u|``, ``n̂ = u / l`` (slides "Springs", "Practical Aspects"):

* Hooke:   ``f_i = k (l - L) n̂``, ``f_j = -f_i``. The slides write
  ``F^int = -k (|x_i - x_j| - L) (x_j - x_i)/|x_i - x_j|``; read as the force on ``x_j``,
  it is the same law (for the worked example, ``F^int = -k (|x - x̄0| - L)(x - x̄0)/|x - x̄0|``
  acts on the moving end ``x``). A stretched spring pulls its ends together.
* damping: ``F^dp = -γ v`` on every particle (slides), and optionally damping along each
  spring ``f_i = c ((v_j - v_i)·n̂) n̂`` that resists stretching rate but not rigid motion.
* gravity: ``G = -g M`` (slides), i.e. ``m_i g`` with ``g = (0, -9.81)`` m/s².

A spring between a fixed and a variable end point moves only the variable one; a spring
between two variable end points splits its force equally and oppositely between them
(slides "Practical Aspects"). The integrators keep fixed particles where they are.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from physlab import _check
from physlab.linear_solver import one_blas_thread

__all__ = ["SpringSystem", "hanging_spring", "chain", "cloth_grid", "soft_box", "grid_edges",
           "critical_time_step"]

#: Largest number of particles the scene builders make (fail fast instead of swapping).
MAX_PARTICLES = 1_000_000


class SpringSystem:
    """Hooke springs between particle pairs, with damping, gravity and fixed particles.

    Parameters
    ----------
    X : (n, d) float array, rest positions (m); ``d`` is 2 or 3.
    edges : (E, 2) int array, particle pairs joined by a spring.
    k : float or (E,) array, stiffness (N/m), >= 0.
    rest_length : None, float or (E,) array (m); default ``|X_i - X_j|``.
    mass : float or (n,) array (kg), > 0 for particles that are not fixed.
    damping : float γ >= 0 (N·s/m) in ``F^dp = -γ v`` (slides).
    fixed : sequence of int, indices of pinned particles.
    gravity : (d,) acceleration (m/s²); default ``(0, -9.81)`` in 2D, ``(0, -9.81, 0)`` in 3D.
    spring_damping : float or (E,) array c >= 0 (N·s/m), damping along each spring.
    ground : None or float, height (m) of a penalty ground plane ``x[:, 1] >= ground``.
    ground_stiffness : penalty stiffness (N/m) of the ground.

    Attributes
    ----------
    X, edges, k, rest_length, mass (n,), damping, spring_damping (E,), fixed (int array),
    gravity (d,), n, d.
    """

    def __init__(self, X, edges, k, rest_length=None, mass=1.0, damping=0.0, fixed=(),
                 gravity=None, spring_damping=0.0, ground=None, ground_stiffness=1e4):
        try:
            X = np.array(X, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"X (rest positions) must be an (n, 2) or (n, 3) array of numbers, "
                             f"got {type(X).__name__} {X!r:.60}") from None
        if X.ndim != 2 or X.shape[1] not in (2, 3):
            raise ValueError(f"X must have shape (n, 2) or (n, 3), got {X.shape}")
        if not np.all(np.isfinite(X)):
            bad = int(np.flatnonzero(~np.isfinite(X).all(1))[0])
            raise ValueError(f"X contains NaN or inf (particle {bad}: {X[bad].tolist()})")
        n, d = X.shape
        try:
            edges = np.array(edges)
            if edges.dtype == object or not (edges.size == 0 or np.issubdtype(edges.dtype,
                                                                               np.number)):
                raise ValueError
        except ValueError:
            raise ValueError(f"edges must be an (E, 2) array of particle indices, got "
                             f"{edges!r:.60}") from None
        if edges.size == 0:
            edges = edges.reshape(0, 2)
        if edges.ndim != 2 or edges.shape[1] != 2:
            raise ValueError(f"edges must have shape (E, 2), got {edges.shape}")
        if not np.issubdtype(edges.dtype, np.integer):
            if not np.all(np.mod(edges, 1) == 0):
                raise ValueError("edges must hold integer particle indices")
            edges = edges.astype(int)
        edges = edges.astype(np.int64)
        if edges.size and (edges.min() < 0 or edges.max() >= n):
            bad = edges[(edges < 0).any(1) | (edges >= n).any(1)][0]
            raise ValueError(f"edge {tuple(int(b) for b in bad)} refers to a particle that does "
                             f"not exist (valid indices 0..{n - 1})")
        if np.any(edges[:, 0] == edges[:, 1]):
            raise ValueError("an edge joins a particle to itself")
        E = len(edges)
        self.X, self.edges, self.n, self.d = X, edges, n, d

        self.k = self._per_edge("k", k, E)
        if rest_length is None:
            rest_length = np.linalg.norm(X[edges[:, 1]] - X[edges[:, 0]], axis=1)
        self.rest_length = self._per_edge("rest_length", rest_length, E)
        self.spring_damping = self._per_edge("spring_damping", spring_damping, E)

        mass = self._floats("mass", mass)
        mass = np.full(n, float(mass)) if mass.ndim == 0 else mass.reshape(-1).copy()
        if mass.shape != (n,):
            raise ValueError(f"mass must be a scalar or shape ({n},), got {mass.shape}")
        if not np.all(np.isfinite(mass)) or np.any(mass < 0):
            i = int(np.flatnonzero(~(np.isfinite(mass) & (mass >= 0)))[0])
            kind = "negative mass" if mass[i] < 0 else "non-finite mass"
            raise ValueError(f"masses must be finite and >= 0: particle {i} has a {kind} "
                             f"{mass[i]}")
        fixed = self._floats("fixed", fixed).reshape(-1)
        if np.any(fixed != np.round(fixed)):
            raise ValueError(f"fixed must hold integer particle indices, got {fixed.tolist()!r:.60}")
        self.fixed = np.unique(fixed.astype(int))
        if self.fixed.size and (self.fixed.min() < 0 or self.fixed.max() >= n):
            raise ValueError(f"fixed refers to particles outside 0..{n - 1}: "
                             f"{self.fixed[(self.fixed < 0) | (self.fixed >= n)].tolist()}")
        free = np.ones(n, bool)
        free[self.fixed] = False
        if np.any(mass[free] <= 0):
            raise ValueError("free (not fixed) particles need a mass > 0")
        self.mass = mass

        self.damping = _check.number(damping, "damping γ (N·s/m)", lo=0)
        if gravity is None:
            gravity = (0.0, -9.81) if d == 2 else (0.0, -9.81, 0.0)
        self.gravity = self._floats("gravity", gravity).reshape(-1)
        if self.gravity.shape != (d,):
            raise ValueError(f"gravity must have {d} components for {d}-D particles, got {gravity!r}")
        if not np.all(np.isfinite(self.gravity)):
            raise ValueError(f"gravity must be finite, got {gravity!r}")
        self.ground = None if ground is None else _check.number(ground, "ground (height)")
        self.ground_stiffness = _check.number(ground_stiffness, "ground_stiffness", lo=0)
        self._pattern = None

    @staticmethod
    def _floats(name, value):
        try:
            return np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be a number or an array of numbers, got "
                             f"{value!r:.60}") from None

    @staticmethod
    def _per_edge(name, value, E):
        a = SpringSystem._floats(name, value)
        a = np.full(E, float(a)) if a.ndim == 0 else a.reshape(-1).copy()
        if a.shape != (E,):
            raise ValueError(f"{name} must be a scalar or shape ({E},) (one per edge), got {a.shape}")
        if not np.all(np.isfinite(a)) or np.any(a < 0):
            raise ValueError(f"{name} must be finite and >= 0")
        return a

    # ------------------------------------------------------------------ state helpers
    def rest_state(self):
        """``(x0, v0)``: the rest positions ``X`` (copied) and zero velocities, ``(n, d)`` each."""
        return self.X.copy(), np.zeros_like(self.X)

    def _check_state(self, x, v=None):
        x = np.asarray(x, dtype=float)
        if x.shape != (self.n, self.d):
            raise ValueError(f"x must have shape {(self.n, self.d)}, got {x.shape}")
        if v is not None:
            v = np.asarray(v, dtype=float)
            if v.shape != x.shape:
                raise ValueError(f"v must have shape {x.shape}, got {v.shape}")
        return x, v

    def _geometry(self, x):
        i, j = self.edges[:, 0], self.edges[:, 1]
        u = x[j] - x[i]  # (E, d)
        length = np.linalg.norm(u, axis=1)
        safe = np.where(length > 1e-12, length, 1.0)
        nhat = u / safe[:, None]
        return i, j, length, safe, nhat

    # ------------------------------------------------------------------ forces and energy
    def spring_forces(self, x, v=None):
        """Per-spring force on the first end point ``f_i`` ``(E, d)`` (Hooke + spring damping)."""
        i, j, length, _, nhat = self._geometry(x)
        mag = self.k * (length - self.rest_length)  # slides "Springs": k (|x_i - x_j| - L)
        if v is not None and np.any(self.spring_damping):
            mag = mag + self.spring_damping * np.einsum("ed,ed->e", v[j] - v[i], nhat)
        return mag[:, None] * nhat

    def force(self, x, v, t=0.0):
        """Total force ``(n, d)`` (N) on every particle: springs, damping, gravity, ground."""
        x, v = self._check_state(x, v)
        fe = self.spring_forces(x, v)
        f = np.zeros_like(x)
        for a in range(self.d):  # scatter: +f_e to i, -f_e to j
            f[:, a] = (np.bincount(self.edges[:, 0], fe[:, a], self.n)
                       - np.bincount(self.edges[:, 1], fe[:, a], self.n))
        f -= self.damping * v  # F^dp = -γ v
        f += self.mass[:, None] * self.gravity  # G = -g M
        if self.ground is not None:
            pen = np.maximum(self.ground - x[:, 1], 0.0)
            f[:, 1] += self.ground_stiffness * pen
        return f

    def potential_energy(self, x):
        """Spring + gravity (+ ground penalty) energy (J); ``force = -grad`` of it when undamped."""
        x, _ = self._check_state(x)
        _, _, length, _, _ = self._geometry(x)
        e = 0.5 * np.sum(self.k * (length - self.rest_length) ** 2)
        e -= np.sum(self.mass * (x @ self.gravity))
        if self.ground is not None:
            pen = np.maximum(self.ground - x[:, 1], 0.0)
            e += 0.5 * self.ground_stiffness * np.sum(pen**2)
        return float(e)

    def kinetic_energy(self, v):
        v = np.asarray(v, dtype=float)
        return float(0.5 * np.sum(self.mass[:, None] * v**2))

    def energy(self, x, v):
        """Total mechanical energy (J): kinetic + spring + gravity (+ ground penalty)."""
        return self.kinetic_energy(v) + self.potential_energy(x)

    # ------------------------------------------------------------------ Jacobians
    def _build_pattern(self):
        """CSR pattern shared by K and D (all diagonal d×d particle blocks + both off-diagonal
        blocks of every spring) and the data slot of every block entry, computed once."""
        n, d = self.n, self.d
        i, j = self.edges[:, 0], self.edges[:, 1]
        a = np.arange(d)
        N = n * d

        def block_keys(bi, bj):  # (m,) block rows/cols -> (m, d, d) linear keys row*N + col
            rows = bi[:, None, None] * d + a[None, :, None]
            cols = bj[:, None, None] * d + a[None, None, :]
            return rows * N + cols

        k_nodes = block_keys(np.arange(n), np.arange(n))
        k_ij, k_ji = block_keys(i, j), block_keys(j, i)
        keys = np.concatenate([k_nodes.ravel(), k_ij.ravel(), k_ji.ravel()])
        uniq, inverse = np.unique(keys, return_inverse=True)
        m1, m2 = k_nodes.size, k_nodes.size + k_ij.size
        self._pattern = dict(
            indptr=np.concatenate([[0], np.cumsum(np.bincount(uniq // N, minlength=N))]),
            indices=(uniq % N).astype(np.int32), nnz=len(uniq), N=N,
            slot_nodes=inverse[:m1].reshape(n, d, d),
            slot_ij=inverse[m1:m2].reshape(-1, d, d), slot_ji=inverse[m2:].reshape(-1, d, d),
            slot_diag=inverse[:m1].reshape(n, d, d)[:, a, a].ravel(),
            # repeated springs between the same pair share slots: then scatter-add instead
            unique_pairs=len(uniq) == m1 + 2 * k_ij.size)
        return self._pattern

    def _assemble(self, blocks, diag):
        """CSR matrix from per-spring blocks ``(E, d, d)`` (+B at (i,i), (j,j), -B at (i,j),
        (j,i)) plus a diagonal ``(n*d,)``; vectorised scatter into the cached pattern."""
        p = self._pattern or self._build_pattern()
        n, d = self.n, self.d
        data = np.zeros(p["nnz"])
        if np.any(blocks):
            i, j = self.edges[:, 0], self.edges[:, 1]
            node = np.empty((n, d, d))
            for r in range(d):  # accumulate diagonal particle blocks: d*d bincounts over springs
                for c in range(d):
                    w = blocks[:, r, c]
                    node[:, r, c] = np.bincount(i, w, n) + np.bincount(j, w, n)
            data[p["slot_nodes"]] = node
            if p["unique_pairs"]:
                data[p["slot_ij"]] = -blocks
                data[p["slot_ji"]] = -blocks
            else:
                data -= np.bincount(p["slot_ij"].ravel(), blocks.ravel(), p["nnz"])
                data -= np.bincount(p["slot_ji"].ravel(), blocks.ravel(), p["nnz"])
        data[p["slot_diag"]] += diag
        return sp.csr_matrix((data, p["indices"], p["indptr"]), shape=(p["N"], p["N"]))

    def force_jacobians(self, x, v, t=0.0):
        """Sparse ``K = ∂f/∂x`` and ``D = ∂f/∂v``, CSR ``(n*d, n*d)`` with the same pattern.

        Row-major flattening: degree of freedom ``i*d + a`` is component ``a`` of particle
        ``i``. Per spring the block ``B = ∂f_i/∂x_i = -k [(1 - L/l) I + (L/l) n̂ n̂ᵀ]``
        enters ``K`` as ``+B`` at ``(i,i), (j,j)`` and ``-B`` at ``(i,j), (j,i)``. Spring
        damping adds ``-c n̂ n̂ᵀ`` to ``D`` the same way and its (non-symmetric) dependence
        on ``x`` to ``K``, so both are exact derivatives of :meth:`force`.
        """
        x, v = self._check_state(x, v)
        i, j, length, safe, nhat = self._geometry(x)
        d = self.d
        I = np.eye(d)
        nn = nhat[:, :, None] * nhat[:, None, :]  # (E, d, d)
        ratio = np.where(length > 1e-12, self.rest_length / safe, 0.0)
        B = -self.k[:, None, None] * ((1 - ratio)[:, None, None] * I + ratio[:, None, None] * nn)
        Dblk = np.zeros_like(B)
        if np.any(self.spring_damping):
            c = self.spring_damping
            w = v[j] - v[i]
            P = I - nn  # projector orthogonal to the spring
            wn = np.einsum("ed,ed->e", w, nhat)
            S = (np.einsum("ea,eb->eab", nhat, np.einsum("ed,edb->eb", w, P))
                 + wn[:, None, None] * P) * (c / safe)[:, None, None]  # ∂f_i/∂u of damping
            B = B - S
            Dblk = -c[:, None, None] * nn
        diagK = np.zeros(self.n * d)
        if self.ground is not None:
            pen = self.ground - x[:, 1] > 0
            diagK[np.arange(self.n)[pen] * d + 1] = -self.ground_stiffness
        diagD = np.full(self.n * d, -self.damping)
        return self._assemble(B, diagK), self._assemble(Dblk, diagD)

    def __repr__(self):
        return (f"SpringSystem(n={self.n}, d={self.d}, springs={len(self.edges)}, "
                f"fixed={self.fixed.size}, damping={self.damping})")


# ---------------------------------------------------------------------------------------
# scene builders


def hanging_spring(anchor=(0.0, 0.0), L=1.0, k=100.0, m=1.0, damping=0.0, g=9.81):
    """The slides' worked example: one spring of rest length ``L`` hanging from the fixed
    point ``x̄0 = anchor``, its free end (particle 1) starting at ``x̄0 + (0, -L)`` at rest,
    i.e. ``y0 = (x̄0 + (0, -L), 0)``. Particle 0 is the fixed end point.

    Static equilibrium: ``x* = x̄0 - (0, L + m g / k)``.
    """
    anchor = _check.vector(anchor, "anchor")
    L = _check.number(L, "L (rest length, m)", lo=0, lo_open=True)
    m = _check.number(m, "m (mass, kg)", lo=0, lo_open=True)
    g = _check.number(g, "g (gravity, m/s²)")
    X = np.stack([anchor, anchor + (0.0, -L)])
    return SpringSystem(X, [[0, 1]], k=k, rest_length=L, mass=[m, m], damping=damping,
                        fixed=[0], gravity=(0.0, -g))


def chain(n_particles=10, length=1.0, k=500.0, total_mass=1.0, damping=0.0, pin="left",
          spring_damping=0.0, anchor=(0.0, 0.0)):
    """A horizontal rope of ``n_particles`` equal masses joined by ``n_particles - 1`` springs,
    starting straight at rest length from ``anchor`` to the right.

    ``pin``: ``"left"`` (first particle fixed), ``"both"`` (both ends) or ``"none"``.
    """
    n_particles = _check.number(n_particles, "n_particles", lo=2, hi=MAX_PARTICLES, integer=True)
    length = _check.number(length, "length (m)", lo=0, lo_open=True)
    total_mass = _check.number(total_mass, "total_mass (kg)", lo=0, lo_open=True)
    X = np.zeros((n_particles, 2))
    X[:, 0] = np.linspace(0.0, length, n_particles)
    X += _check.vector(anchor, "anchor")
    edges = np.stack([np.arange(n_particles - 1), np.arange(1, n_particles)], 1)
    fixed = {"left": [0], "both": [0, n_particles - 1], "none": []}.get(pin)
    if fixed is None:
        raise ValueError(f"unknown pin {pin!r}; valid: left, both, none")
    return SpringSystem(X, edges, k=k, mass=total_mass / n_particles, damping=damping,
                        fixed=fixed, spring_damping=spring_damping)


def _grid_size(nx, ny, what):
    """``(nx, ny)`` as whole numbers >= 2 with at most :data:`MAX_PARTICLES` particles."""
    nx = _check.number(nx, f"{what} nx", lo=2, integer=True)
    ny = _check.number(ny, f"{what} ny", lo=2, integer=True)
    if nx * ny > MAX_PARTICLES:
        raise ValueError(f"a {what} of {nx} × {ny} = {nx * ny:,} particles is more than the "
                         f"limit of {MAX_PARTICLES:,}; use fewer particles")
    return nx, ny


def grid_edges(nx, ny, shear=True, bend=True):
    """Edges of an ``nx × ny`` lattice (particle ``r*nx + c`` at column ``c``, row ``r``):
    structural (horizontal/vertical neighbours), shear (diagonals) and bend (two apart).
    Returns ``(edges (E, 2) int, kind (E,) str array in {"structural", "shear", "bend"})``.
    """
    idx = np.arange(nx * ny).reshape(ny, nx)
    parts, kinds = [], []

    def add(a, b, kind):
        e = np.stack([a.reshape(-1), b.reshape(-1)], 1)
        parts.append(e)
        kinds.extend([kind] * len(e))

    add(idx[:, :-1], idx[:, 1:], "structural")
    add(idx[:-1, :], idx[1:, :], "structural")
    if shear:
        add(idx[:-1, :-1], idx[1:, 1:], "shear")
        add(idx[:-1, 1:], idx[1:, :-1], "shear")
    if bend:
        add(idx[:, :-2], idx[:, 2:], "bend")
        add(idx[:-2, :], idx[2:, :], "bend")
    return np.concatenate(parts).astype(np.int64), np.array(kinds)


def cloth_grid(nx=20, ny=20, width=1.0, height=1.0, k=2000.0, k_shear=None, k_bend=None,
               total_mass=1.0, damping=0.05, spring_damping=0.0, pin="top_corners", dim=2):
    """A cloth of ``nx × ny`` particles with structural, shear and bend springs.

    ``dim=2``: a net hanging in the vertical x–y plane, top row at ``y = 0``.
    ``dim=3``: a sheet in the horizontal x–z plane at ``y = 0`` (gravity −y drapes it).
    ``pin``: ``"top_corners"`` (the two corners of the first row in 3D / top row in 2D),
    ``"top_left"``, ``"top_row"``, ``"none"``, or a sequence of particle indices (particle
    ``r*nx + c`` is column ``c`` of row ``r``). Shear and bend stiffness default to ``k/2``
    and ``k/10``.
    """
    nx, ny = _grid_size(nx, ny, "cloth")
    if dim not in (2, 3) or isinstance(dim, bool):
        raise ValueError(f"dim must be 2 or 3, got {dim!r}")
    width = _check.number(width, "width (m)", lo=0, lo_open=True)
    height = _check.number(height, "height (m)", lo=0, lo_open=True)
    total_mass = _check.number(total_mass, "total_mass (kg)", lo=0, lo_open=True)
    u, w = np.meshgrid(np.linspace(0, width, nx), np.linspace(0, height, ny))
    if dim == 2:
        X = np.stack([u.reshape(-1), -w.reshape(-1)], 1)
    else:
        X = np.stack([u.reshape(-1), np.zeros(nx * ny), w.reshape(-1)], 1)
    edges, kind = grid_edges(nx, ny)
    kk = np.where(kind == "structural", k,
                  np.where(kind == "shear", k / 2 if k_shear is None else k_shear,
                           k / 10 if k_bend is None else k_bend))
    named = {"top_corners": [0, nx - 1], "top_left": [0], "top_row": list(range(nx)), "none": []}
    if isinstance(pin, str):
        if pin not in named:
            raise ValueError(f"unknown pin {pin!r}; valid: {', '.join(named)} or a list of indices")
        fixed = named[pin]
    else:
        fixed = list(pin)
    return SpringSystem(X, edges, k=kk, mass=total_mass / (nx * ny), damping=damping,
                        fixed=fixed, spring_damping=spring_damping)


def soft_box(nx=6, ny=6, size=0.5, k=3000.0, total_mass=1.0, damping=0.1, spring_damping=1.0,
             drop_height=0.5, ground=0.0, ground_stiffness=2e4, tilt=0.3):
    """A square jelly block (lattice with structural + shear springs) held ``drop_height``
    above a penalty ground, tilted by ``tilt`` radians so it lands on a corner and tumbles."""
    nx, ny = _grid_size(nx, ny, "soft box")
    size = _check.number(size, "size (m)", lo=0, lo_open=True)
    total_mass = _check.number(total_mass, "total_mass (kg)", lo=0, lo_open=True)
    drop_height = _check.number(drop_height, "drop_height (m)")
    tilt = _check.number(tilt, "tilt (rad)")
    ground = _check.number(ground, "ground (height, m)")
    edges, kind = grid_edges(nx, ny, shear=True, bend=False)
    u, w = np.meshgrid(np.linspace(-size / 2, size / 2, nx), np.linspace(-size / 2, size / 2, ny))
    P = np.stack([u.reshape(-1), w.reshape(-1)], 1)
    c, s = np.cos(tilt), np.sin(tilt)
    X = P @ np.array([[c, s], [-s, c]]) + (0.0, ground + drop_height + size)
    kk = np.where(kind == "structural", k, k / 2)
    return SpringSystem(X, edges, k=kk, mass=total_mass / (nx * ny), damping=damping,
                        spring_damping=spring_damping, ground=ground, ground_stiffness=ground_stiffness)


def critical_time_step(system):
    """``2 / ω_max``: the largest stable step of semi-implicit (symplectic) Euler for the
    linearised, undamped system at rest (``ω_max²`` = largest eigenvalue of ``-M^-1 K`` over
    the free particles). Explicit Euler has no such step without damping: it gains energy at
    every ``dt`` (lesson 01). Dense eigenvalues: for lesson-sized systems (≲ 1,000 dofs).

    ``system``: a :class:`SpringSystem` with at most 4,000 unknowns ``n·d``. Returns the
    step in s."""
    from scipy.linalg import eigh

    if not isinstance(system, SpringSystem):
        raise TypeError(f"system must be a physlab.springs.SpringSystem (e.g. chain()), "
                        f"got {type(system).__name__}")
    if system.n * system.d > 4000:
        raise ValueError(f"critical_time_step uses dense eigenvalues; the system has "
                         f"{system.n * system.d} unknowns (limit 4000): use a smaller system")
    x, v = system.rest_state()
    K, _ = system.force_jacobians(x, v)
    d = system.d
    free = np.setdiff1d(np.arange(system.n), system.fixed)
    dofs = (free[:, None] * d + np.arange(d)).ravel()
    Kf = -K.toarray()[np.ix_(dofs, dofs)]
    m = np.repeat(system.mass, d)[dofs]
    with one_blas_thread():
        w2 = eigh(0.5 * (Kf + Kf.T), np.diag(m), eigvals_only=True)[-1]
    return float(2.0 / np.sqrt(max(w2, 1e-300)))
