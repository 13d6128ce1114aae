"""Optional compiled Fixed Corotated FEM forces (numba): :class:`CorotatedFEMNumba`.

Same model, constructor and ``forces(x)`` as :class:`physlab.fem.CorotatedFEM` (PhysAnimator
supp. Eqs. 4–6, Fixed Corotated stress Eq. 5), evaluated by two numba kernels instead of
numpy ufuncs:

1. a ``prange`` over triangles computes ``F = Ds Dm^-1`` (Eq. 6), the polar rotation (closed
   2×2 form ``θ = atan2(F10 - F01, F00 + F11)``: ``cos θ, sin θ = (F00 + F11, F10 - F01) / r``),
   ``V P`` (Eq. 5) and the three corner forces ``[f1, f2] = -V P Dm^-T``, ``f0 = -(f1 + f2)``
   (Eq. 4) into a (3T, 2) buffer, row ``k T + t`` for corner ``k`` of triangle ``t``;
2. a ``prange`` over *vertices* sums the rows of the triangles around each vertex, using a
   vertex → (corner, triangle) adjacency in CSR form built once in the constructor.

Step 2 is a gather, not a scatter: no two threads write to the same vertex (no atomics, no
per-thread copies), and every vertex sums its contributions in one fixed order, so the
result does not depend on the number of threads. That order is the one in which
``np.bincount`` adds them in :meth:`CorotatedFEM.forces` (corner 0 of every triangle, then
corner 1, then corner 2), and the per-triangle arithmetic follows the same operation order
(``fastmath=False``). The one difference: ``r = sqrt(c² + s²)`` instead of ``np.hypot``
(half the cost of the whole triangle kernel; ``hypot`` is kept for ``r < 1e-150``, where the
squares would underflow), so the two classes agree to a few ulps (≈ 1e-16 relative).

Meshes of fewer than :data:`PARALLEL_MIN_TRIANGLES` triangles use single-threaded builds of
the same kernels (see :class:`CorotatedFEMNumba`).

numba is an optional dependency: importing this module never imports numba. The first
:class:`CorotatedFEMNumba` of a process compiles the kernels (≈ 2 s; ``cache=True`` keeps
the machine code in ``physlab/__pycache__``, so later processes load it in ≈ 0.3 s) and
raises ImportError with an explanation when numba is not installed;
:func:`numba_available` tells beforehand.
"""
from __future__ import annotations

import math

import numpy as np

from physlab.fem import CorotatedFEM

__all__ = ["CorotatedFEMNumba", "numba_available", "compile_kernels", "vertex_adjacency",
           "PARALLEL_MIN_TRIANGLES"]

# ``prange`` is rebound to ``numba.prange`` by :func:`compile_kernels` before the kernels are
# compiled; until then (and without numba) the kernels below are plain, slow Python.
prange = range

_KERNELS = None  # {"parallel": (corner, gather), "serial": (corner, gather)} once compiled

#: :class:`CorotatedFEMNumba` runs its multi-threaded kernels from this many triangles on.
PARALLEL_MIN_TRIANGLES = 5_000


def numba_available():
    """True when ``import numba`` works in this environment."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def _corner_forces(x, i0, i1, i2, b00, b01, b10, b11, muV, lamV, W):
    """Corner forces of every triangle into ``W`` (3T, 2); row ``k T + t`` = corner ``k`` of
    triangle ``t``. Operation order as in :meth:`physlab.fem.CorotatedFEM.forces`."""
    T = i0.shape[0]
    for t in prange(T):
        p, q, s = i0[t], i1[t], i2[t]
        x0, y0 = x[p, 0], x[p, 1]
        e1x, e1y = x[q, 0] - x0, x[q, 1] - y0
        e2x, e2y = x[s, 0] - x0, x[s, 1] - y0
        B00, B01, B10, B11 = b00[t], b01[t], b10[t], b11[t]
        # F = Ds Dm^-1, Eq. (6), row major (a b; c d)
        a = e1x * B00 + e2x * B10
        b = e1x * B01 + e2x * B11
        c = e1y * B00 + e2y * B10
        d = e1y * B01 + e2y * B11
        # polar rotation R = [[cs, -sn], [sn, cs]]; R = I when F00 + F11 = F10 - F01 = 0
        cs = a + d
        sn = c - b
        r = math.sqrt(cs * cs + sn * sn)
        if r < 1e-150:  # sqrt would lose the squares to underflow: use hypot
            r = math.hypot(cs, sn)
        if r == 0.0:
            r = 1.0
            cs = 1.0
        cs = cs / r
        sn = sn / r
        # g = λV (J - 1); V P = 2μV (F - R) + g cof(F), cof(F) = [[d, -c], [-b, a]] (Eq. 5)
        g = a * d
        g = g - b * c
        g = g - 1.0
        g = g * lamV[t]
        m = muV[t]
        p00 = (a - cs) * m + g * d
        p01 = (b + sn) * m - g * c
        p10 = (c - sn) * m - g * b
        p11 = (d - cs) * m + g * a
        # [f1, f2] = -(V P) Dm^-T (Eq. 4), f0 = -(f1 + f2)
        f1 = p00 * B00 + p01 * B01
        f2 = p00 * B10 + p01 * B11
        W[t, 0] = f1 + f2
        W[T + t, 0] = -f1
        W[2 * T + t, 0] = -f2
        f1 = p10 * B00 + p11 * B01
        f2 = p10 * B10 + p11 * B11
        W[t, 1] = f1 + f2
        W[T + t, 1] = -f1
        W[2 * T + t, 1] = -f2


def _gather(ptr, adj, W, f):
    """``f[v] = Σ_{j in ptr[v]:ptr[v+1]} W[adj[j]]`` for every vertex (race-free gather)."""
    n = ptr.shape[0] - 1
    for v in prange(n):
        sx = 0.0
        sy = 0.0
        for j in range(ptr[v], ptr[v + 1]):
            e = adj[j]
            sx += W[e, 0]
            sy += W[e, 1]
        f[v, 0] = sx
        f[v, 1] = sy


def _renamed(func, suffix):
    """A copy of ``func`` under another name, so that numba caches its second compilation
    (other flags) in files of its own."""
    import types

    g = types.FunctionType(func.__code__, func.__globals__, func.__name__ + suffix,
                           func.__defaults__, func.__closure__)
    g.__qualname__ = func.__qualname__ + suffix
    g.__doc__ = func.__doc__
    return g


def compile_kernels():
    """Compile (or load from numba's cache) the kernels and return them as a dict
    ``{"parallel": (corner_forces, gather), "serial": (corner_forces, gather)}``. Raises
    ImportError with an explanation when numba is missing. Called by :class:`CorotatedFEMNumba`."""
    global _KERNELS, prange
    if _KERNELS is None:
        try:
            import numba
        except ImportError as err:
            raise ImportError(
                "physlab.fem_numba.CorotatedFEMNumba needs the optional package numba "
                "(pip install numba); physlab.fem.CorotatedFEM computes the same forces "
                "with numpy alone") from err
        from numba import types

        prange = numba.prange  # serial builds (parallel=False) treat it as range

        def arr(dtype, ndim, readonly=True):
            return types.Array(dtype, ndim, "C", readonly=readonly)

        # Explicit signatures: compiled (or loaded from the cache) once, here. Inputs are
        # typed read-only, so writeable and read-only arrays (e.g. a TriMesh's X) share them.
        f8, i8 = types.float64, types.int64
        corner_sig = types.void(arr(f8, 2), *[arr(i8, 1)] * 3, *[arr(f8, 1)] * 6,
                                arr(f8, 2, readonly=False))
        gather_sig = types.void(arr(i8, 1), arr(i8, 1), arr(f8, 2), arr(f8, 2, readonly=False))
        kernels = {}
        for flavour, parallel in (("parallel", True), ("serial", False)):
            opts = dict(parallel=parallel, cache=True, fastmath=False, nogil=True)
            suffix = "" if parallel else "_serial"
            kernels[flavour] = (
                numba.njit(corner_sig, **opts)(_renamed(_corner_forces, suffix)),
                numba.njit(gather_sig, **opts)(_renamed(_gather, suffix)))
        _KERNELS = kernels
    return _KERNELS


def vertex_adjacency(tris, n):
    """CSR vertex → corner-row adjacency ``(ptr (n+1,), adj (3T,))`` of a (T, 3) mesh.

    ``adj[ptr[v]:ptr[v+1]]`` lists the rows ``k T + t`` (corner ``k`` of triangle ``t``) whose
    vertex is ``v``, in increasing row order (the order ``np.bincount`` adds them in)."""
    tris = np.asarray(tris)
    idx = np.ascontiguousarray(tris.T).reshape(-1)  # rows k T + t: corner k of triangle t
    adj = np.argsort(idx, kind="stable").astype(np.int64)
    ptr = np.zeros(n + 1, np.int64)
    np.cumsum(np.bincount(idx, minlength=n), out=ptr[1:])
    return ptr, adj


class CorotatedFEMNumba(CorotatedFEM):
    """:class:`physlab.fem.CorotatedFEM` with ``forces`` computed by compiled numba kernels.

    Same parameters (``X`` (n, 2), ``tris`` (T, 3), ``mu``, ``lam`` scalars or (T,)) and the
    same results to rounding; ``energy`` and ``deformation_gradients`` are inherited. The
    first construction in a process compiles the kernels, or loads them from numba's cache.
    Raises ImportError when numba is not installed.

    ``parallel`` (keyword only): ``None`` (default) runs the multi-threaded kernels from
    :data:`PARALLEL_MIN_TRIANGLES` triangles on and the single-threaded ones below;
    ``True`` / ``False`` force either. Both give identical results. Small meshes stay
    single-threaded because a parallel region waits for its slowest thread: on a machine
    whose other cores are busy, a 2,000-triangle evaluation that takes 0.03 ms on one
    thread was measured at several milliseconds with two.
    """

    def __init__(self, X, tris, mu, lam, *, parallel=None):
        kernels = compile_kernels()
        super().__init__(X, tris, mu, lam)
        T = len(self.V)
        if parallel is None:
            parallel = T >= PARALLEL_MIN_TRIANGLES
        self.parallel = bool(parallel)
        self._corner_forces, self._gather = kernels["parallel" if self.parallel else "serial"]
        Dm_inv = self.Dm_inv
        self._Bc = tuple(np.ascontiguousarray(Dm_inv[:, i, j]) for i in range(2) for j in range(2))
        self._muVc = np.ascontiguousarray(2.0 * self.mu * self.V)
        self._lamVc = np.ascontiguousarray(self.lam * self.V)
        self._tri_cols = tuple(np.ascontiguousarray(self.tris[:, k], dtype=np.int64)
                               for k in range(3))
        self._ptr, self._adj = vertex_adjacency(self.tris, self.n)
        self._W = np.empty((3 * T, 2))

    def forces(self, x, out=None):
        """Elastic forces ``-∂E/∂x`` (n, 2), Eqs. (4–6). ``out``: optional writeable
        C-contiguous float64 (n, 2) array to write into (and return)."""
        x = np.ascontiguousarray(x, dtype=np.float64)
        if x.shape != (self.n, 2):
            raise ValueError(f"x must have shape ({self.n}, 2), got {x.shape}")
        if out is None:
            out = np.empty((self.n, 2))
        elif (not isinstance(out, np.ndarray) or out.shape != (self.n, 2)
              or out.dtype != np.float64 or not out.flags.c_contiguous
              or not out.flags.writeable):
            raise ValueError(f"out must be a writeable C-contiguous float64 ({self.n}, 2) array")
        i0, i1, i2 = self._tri_cols
        b00, b01, b10, b11 = self._Bc
        self._corner_forces(x, i0, i1, i2, b00, b01, b10, b11, self._muVc, self._lamVc, self._W)
        self._gather(self._ptr, self._adj, self._W, out)
        return out
