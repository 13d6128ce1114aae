"""Sparse linear solvers for the implicit-Euler systems ``(M - h D - h^2 K) dv = b``.

:func:`physlab.integrators.simulate` solves one such system per Newton iteration
(``M`` masses, ``K = df/dx``, ``D = df/dv``, ``h`` the time step; the matrix of
D. Baraff and A. Witkin, "Large steps in cloth simulation", SIGGRAPH 1998, Eq. (6)). The
matrix changes little from one solve to the next, which :class:`LinearSolver` exploits by
keeping factors and warm starts across solves.
"""
from __future__ import annotations

import contextlib
import functools
from typing import Sequence

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

__all__ = ["ConvergenceError", "LinearSolver", "DENSE_MAX", "one_blas_thread"]


class ConvergenceError(RuntimeError):
    """Newton–Raphson (:mod:`physlab.integrators`) or conjugate gradients
    (:class:`LinearSolver`) did not converge. ``residuals`` holds the residual norm per
    iteration (empty for a linear solver)."""

    def __init__(self, message: str, residuals: Sequence[float]):
        super().__init__(message)
        self.residuals = list(residuals)


@functools.lru_cache(maxsize=1)
def _blas_controller():
    """A ``threadpoolctl.ThreadpoolController`` (inspecting the loaded libraries is the
    expensive part, so it is made once), or None without threadpoolctl."""
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:
        return None
    return ThreadpoolController()


def one_blas_thread():
    """Context manager: BLAS/LAPACK on one thread (a no-op without threadpoolctl).

    For small or memory-bound linear algebra, where threads only cost: on a 2-core machine
    under load a threaded 128×128 ``numpy.linalg.solve`` took 12× longer in total, with
    single calls up to 0.13 s; conjugate gradients' level-1/2 work does not speed up either."""
    c = _blas_controller()
    return contextlib.nullcontext() if c is None else c.limit(limits=1, user_api="blas")


#: Systems with at most this many unknowns are solved densely (``numpy.linalg.solve``) by
#: every :class:`LinearSolver` kind: exact, and faster than building sparse factors.
DENSE_MAX = 64


class LinearSolver:
    """Sparse solver for the implicit-Euler systems ``A dv = b``, kept across steps.

    ``kind``:

    * ``"direct"``: a fresh SuperLU factorisation per solve. Robust for any non-singular
      ``A``; its cost grows quickly with size (fill-in). Above 2,000 unknowns the rows and
      columns are first reordered by METIS nested dissection (computed once per sparsity
      pattern), else SuperLU's COLAMD ordering is used.
    * ``"cg"``: conjugate gradients with a Jacobi preconditioner, warm-started from the
      previous solution; needs ``A`` symmetric positive definite (true for springs that
      are not strongly compressed).
    * ``"lagged"``: conjugate gradients preconditioned by the SuperLU factors of an
      *earlier* matrix. The matrix ``M - h D - h^2 K`` changes little from one Newton
      iteration or time step to the next, so the old factors are an excellent
      preconditioner; the factorisation is refreshed only when CG needs more than
      ``refactor_after`` iterations (or fails), and then used directly.
    * ``"auto"``: ``"direct"`` below 1,000 unknowns, ``"lagged"`` above (measured in
      ``benchmarks/bench_springs.py``: lagged is 2–3× faster from ~2,000 unknowns).

    ``rtol`` is the relative residual at which the iterative kinds stop.
    ``stats`` counts factorisations, solves and CG iterations.
    """

    KINDS = ("auto", "direct", "cg", "lagged")

    def __init__(self, kind="auto", rtol=1e-8, refactor_after=6):
        if kind not in self.KINDS:
            raise ValueError(f"unknown solver {kind!r}; valid solvers are: {', '.join(self.KINDS)}")
        self.kind, self.rtol, self.refactor_after = kind, rtol, refactor_after
        self._lu = None
        self._lu_shape = None
        self._perm = None
        self.stats = dict(factorizations=0, solves=0, cg_iterations=0)

    #: ``"auto"`` uses ``"direct"`` below this many unknowns, ``"lagged"`` from here on
    AUTO_DIRECT_BELOW = 1000

    def resolve(self, n_unknowns):
        """The kind actually used for a system of ``n_unknowns`` (resolves ``"auto"``)."""
        if self.kind != "auto":
            return self.kind
        return "direct" if n_unknowns < self.AUTO_DIRECT_BELOW else "lagged"

    def _ordering(self, A):
        """Fill-reducing permutation of ``A``'s graph, cached while the pattern is unchanged.

        Nested dissection from METIS (pymetis) when available: on a 100×100 cloth with bend
        springs it gives 4.8M factor entries against 7.4M with SuperLU's COLAMD (similar fill
        on small meshes). ``None`` means: let SuperLU use COLAMD.
        """
        key = (A.shape, A.nnz)
        if self._perm is not None and self._perm[0] == key and np.array_equal(self._perm[1], A.indices):
            return self._perm[2]
        try:
            import pymetis
        except ImportError:  # optional: fall back to COLAMD
            perm = None
        else:
            G = sp.csr_matrix((np.ones(A.nnz), A.indices, A.indptr), shape=A.shape)
            G = (G + G.T).tocsr()
            G.setdiag(0)
            G.eliminate_zeros()
            perm, _ = pymetis.nested_dissection(  # A'[i, j] = A[perm[i], perm[j]]
                adjacency=pymetis.CSRAdjacency(G.indptr, G.indices))
            perm = np.asarray(perm)
        self._perm = (key, A.indices.copy(), perm)
        return perm

    def _factor(self, A):
        """SuperLU factors of ``A`` as a callable ``b -> A^-1 b``."""
        self.stats["factorizations"] += 1
        A = sp.csr_matrix(A)
        perm = self._ordering(A) if A.shape[0] >= 2000 else None
        if perm is None:
            lu = spla.splu(sp.csc_matrix(A), permc_spec="COLAMD")
            self._lu = lu.solve
        else:
            lu = spla.splu(sp.csc_matrix(A[perm][:, perm]), permc_spec="NATURAL",
                           options=dict(SymmetricMode=True))

            def solve(b, lu=lu, perm=perm):
                z = np.empty_like(b)
                z[perm] = lu.solve(b[perm])
                return z

            self._lu = solve
        self._lu_shape = A.shape
        return self._lu

    def _cg(self, A, b, x0, precond, maxiter, rtol=None):
        count = [0]

        def cb(_):
            count[0] += 1

        # CG alternates triangular solves (scipy's BLAS) with dot products (numpy's BLAS):
        # memory-bound level-1/2 work that threads do not speed up, while two competing
        # thread pools on a small machine slow every iteration down several-fold.
        with one_blas_thread():
            z, info = spla.cg(A, b, x0=x0, rtol=self.rtol if rtol is None else rtol, atol=0.0, maxiter=maxiter,
                              M=precond, callback=cb)
        self.stats["cg_iterations"] += count[0]
        return z, info, count[0]

    def solve(self, A, b, x0=None, rtol=None):
        """Solve ``A z = b`` (``A`` sparse ``(N, N)``, ``b`` ``(N,)``).

        ``x0`` warm-starts CG; ``rtol`` (iterative kinds) overrides the default tolerance
        for this solve, e.g. an inexact-Newton forcing term."""
        self.stats["solves"] += 1
        if A.shape[0] <= DENSE_MAX:  # tiny systems: LAPACK beats any sparse machinery
            with one_blas_thread():  # threads cost more than they gain
                return np.linalg.solve(A.toarray(), b)
        kind = self.resolve(A.shape[0])
        if kind == "direct":
            z = self._factor(A)(b)
        elif kind == "cg":
            diag = A.diagonal()
            if np.any(diag <= 0):
                raise ConvergenceError("solver='cg' needs a positive diagonal; use 'direct'", [])
            P = spla.LinearOperator(A.shape, matvec=lambda r: r / diag, dtype=A.dtype)
            z, info, _ = self._cg(A, b, x0, P, 20 * A.shape[0], rtol)
            if info != 0:
                raise ConvergenceError(f"conjugate gradients did not converge (info={info}); "
                                       "use solver='direct'", [])
        elif self._lu is None or self._lu_shape != A.shape:
            z = self._factor(A)(b)
        else:  # lagged factorisation as preconditioner
            P = spla.LinearOperator(A.shape, matvec=self._lu, dtype=A.dtype)
            z, info, its = self._cg(A, b, x0, P, 4 * self.refactor_after, rtol)
            if info != 0:
                z = self._factor(A)(b)
            elif its > self.refactor_after:
                self._factor(A)  # the next solves get a fresh preconditioner
        return z

