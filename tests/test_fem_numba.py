"""physlab.fem_numba: the optional numba forces agree with physlab.fem.CorotatedFEM.

numba is optional: the agreement tests are skipped without it, and the module itself must
import (and fail with a clear ImportError on use) when numba is missing.
"""
import sys

import numpy as np
import pytest

from physlab import fem
from physlab import fem_numba
from physlab.mesh import disk_mesh, grid_mesh, strip_mesh

needs_numba = pytest.mark.skipif(not fem_numba.numba_available(),
                                 reason="numba is not installed (optional compiled FEM path)")


def perturbed(X, scale, seed):
    """Rest positions moved by Gaussian noise of ``scale`` (large enough to invert some)."""
    rng = np.random.default_rng(seed)
    return X + scale * rng.standard_normal(X.shape)


def signed_dets(model, x):
    F = model.deformation_gradients(x)
    return F[:, 0, 0] * F[:, 1, 1] - F[:, 0, 1] * F[:, 1, 0]


def rel_diff(a, b):
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


def test_imports_without_numba_and_explains(monkeypatch):
    """Without numba the module imports, and constructing the model says what to install."""
    monkeypatch.setitem(sys.modules, "numba", None)  # makes `import numba` raise ImportError
    monkeypatch.setattr(fem_numba, "_KERNELS", None)
    assert fem_numba.numba_available() is False
    mesh = grid_mesh(2, 2, 1.0, 1.0)
    with pytest.raises(ImportError, match="pip install numba"):
        fem_numba.CorotatedFEMNumba(mesh.X, mesh.tris, 1.0, 1.0)


def test_vertex_adjacency_lists_every_corner_in_bincount_order():
    mesh = disk_mesh((0.0, 0.0), 5.0, max_area=2.0)
    tris = mesh.tris
    T = len(tris)
    ptr, adj = fem_numba.vertex_adjacency(tris, len(mesh.X))
    assert ptr[0] == 0 and ptr[-1] == 3 * T and np.all(np.diff(ptr) >= 1)
    assert np.array_equal(np.sort(adj), np.arange(3 * T))
    for v in range(len(mesh.X)):
        rows = adj[ptr[v]:ptr[v + 1]]
        assert np.all(np.diff(rows) > 0)  # increasing: the order np.bincount adds them in
        assert np.all(tris[rows % T, rows // T] == v)


@needs_numba
@pytest.mark.parametrize("parallel", [None, False, True])
def test_matches_corotated_fem_with_inverted_triangles(parallel):
    mesh = disk_mesh((0.0, 0.0), 10.0, max_area=1.5)
    X, tris = mesh.X, mesh.tris
    T = len(tris)
    rng = np.random.default_rng(7)
    mu = rng.uniform(50.0, 500.0, T)  # per-triangle materials
    lam = rng.uniform(100.0, 2000.0, T)
    ref = fem.CorotatedFEM(X, tris, mu, lam)
    model = fem_numba.CorotatedFEMNumba(X, tris, mu, lam, parallel=parallel)
    assert model.parallel == (T >= fem_numba.PARALLEL_MIN_TRIANGLES if parallel is None
                              else parallel)
    for seed, scale in ((0, 0.05), (1, 0.4), (2, 1.0)):
        x = perturbed(X, scale, seed)
        if scale >= 0.4:
            assert np.any(signed_dets(ref, x) < 0), "the test state should invert triangles"
        f_ref = ref.forces(x)
        f = model.forces(x)
        assert f.shape == (len(X), 2) and f.dtype == np.float64
        assert rel_diff(f, f_ref) <= 1e-10
        assert rel_diff(f, fem.elastic_forces(x, X, tris, mu, lam)) <= 1e-10
        assert np.abs(f.sum(axis=0)).max() <= 1e-9 * np.abs(f).max()  # no net force
    # rest state: no force; everything collapsed to one point (F = 0, R = I): still finite
    assert np.abs(model.forces(X)).max() <= 1e-9 * (mu.max() + lam.max())
    x0 = np.zeros_like(X)
    assert rel_diff(model.forces(x0), ref.forces(x0)) <= 1e-10


@needs_numba
def test_large_mesh_parallel_is_deterministic_and_matches():
    mesh = strip_mesh(3 * fem_numba.PARALLEL_MIN_TRIANGLES)
    mu, lam = fem.lame_parameters(2e5, 0.3)
    model = fem_numba.CorotatedFEMNumba(mesh.X, mesh.tris, mu, lam)
    assert model.parallel
    serial = fem_numba.CorotatedFEMNumba(mesh.X, mesh.tris, mu, lam, parallel=False)
    x = perturbed(mesh.X, 0.3, 3)
    f = model.forces(x)
    # the vertex gather sums in a fixed order: bit-identical whatever the threads
    assert np.array_equal(f, model.forces(x))
    assert np.array_equal(f, serial.forces(x))
    assert rel_diff(f, fem.CorotatedFEM(mesh.X, mesh.tris, mu, lam).forces(x)) <= 1e-10


@needs_numba
def test_input_layouts_out_argument_and_errors():
    mesh = grid_mesh(6, 4, 3.0, 2.0)
    model = fem_numba.CorotatedFEMNumba(mesh.X, mesh.tris, 10.0, 20.0)
    x = perturbed(mesh.X, 0.1, 4)
    expected = fem.CorotatedFEM(mesh.X, mesh.tris, 10.0, 20.0).forces(x)
    # Fortran order, a strided view, a read-only array and a list all work
    xf = np.asfortranarray(x)
    wide = np.zeros((len(x), 4))
    wide[:, ::2] = x
    ro = x.copy()
    ro.flags.writeable = False
    for xi in (xf, wide[:, ::2], ro, x.tolist()):
        assert rel_diff(model.forces(xi), expected) <= 1e-10
    out = np.full_like(x, np.nan)
    assert model.forces(x, out=out) is out
    assert rel_diff(out, expected) <= 1e-10
    with pytest.raises(ValueError, match="shape"):
        model.forces(x[:-1])
    with pytest.raises(ValueError, match="out must be"):
        model.forces(x, out=np.empty((len(x), 2), np.float32))
    # energy is inherited from CorotatedFEM
    assert model.energy(x) == pytest.approx(fem.elastic_energy(x, mesh.X, mesh.tris, 10.0, 20.0))
