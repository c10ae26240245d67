"""The fill-reducing ordering kept per sparsity pattern (multilayer.numerics.ordering) and the SuperLU backend on it."""

import doctest

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from runs import run_cli

import multilayer.numerics.linsolve
import multilayer.numerics.ordering
from multilayer.numerics.linsolve import Reuse, ReusingSolver, SolverStats, factorize
from multilayer.numerics.ordering import nested_dissection, pattern_key


def test_doctests():
    assert doctest.testmod(multilayer.numerics.ordering).failed == 0


def laplacian(n: int) -> sp.csc_matrix:
    T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
    return (sp.kron(sp.eye(n), T) + sp.kron(T, sp.eye(n))).tocsc()


def fill(lu) -> int:
    return lu.L.nnz + lu.U.nnz


def test_nested_dissection_fills_less_than_colamd_and_grows_like_n_log_n():
    """On the 5-point Laplacian nested dissection's fill per row grows like log N (George 1973);
    COLAMD's grows faster.  Measured per row at N = 1600 / 6400: ND 28.7 / 37.6, COLAMD 40.6 / 57.9."""
    per_row = {}
    for n in (40, 80):
        A = laplacian(n)
        p = nested_dissection(A)
        assert sorted(p.tolist()) == list(range(n * n))
        nd = spla.splu(A[p][:, p].tocsc(), permc_spec="NATURAL", diag_pivot_thresh=1e-3,
                       options={"SymmetricMode": True})
        colamd = spla.splu(A, permc_spec="COLAMD")
        per_row[n] = (fill(nd) / n**2, fill(colamd) / n**2)
    assert per_row[80][0] <= 0.75 * per_row[80][1]
    # ×4 unknowns: ND adds about a constant per row (log N), COLAMD more than that
    assert per_row[80][0] - per_row[40][0] < per_row[80][1] - per_row[40][1]
    assert per_row[80][0] / per_row[40][0] < 1.5


def test_the_ordering_belongs_to_the_pattern_not_the_values():
    """A matrix with stored zeros (a fluid at rest) gets the ordering of its pattern: a run resumed
    mid-way orders its first matrix as the uninterrupted run did, so the two stay bit-identical."""
    A = laplacian(12).tocsr()
    B = A.copy()
    B.data[::3] = 0.0  # stored, but zero
    assert B.nnz == A.nnz and pattern_key(A) == pattern_key(B)
    assert np.array_equal(nested_dissection(A), nested_dissection(B))


def test_superlu_orders_each_pattern_once(monkeypatch):
    calls = []

    def counting(A):
        calls.append(A.shape)
        return nested_dissection(A)

    monkeypatch.setattr(multilayer.numerics.linsolve, "nested_dissection", counting)
    stats = SolverStats()
    A = laplacian(10)
    b = np.arange(100.0)
    for k in range(3):  # one pattern, three matrices
        x = factorize(A * (1.0 + k), stats).solve(b)
        assert np.linalg.norm(A * (1.0 + k) @ x - b) <= 1e-13 * np.linalg.norm(b)
    assert calls == [(100, 100)] and stats.factorizations == 3
    factorize(laplacian(11), stats)  # another pattern: its own ordering
    assert calls == [(100, 100), (121, 121)]
    factorize(A, SolverStats())  # another solver owns its own orderings
    assert len(calls) == 3


def test_saddle_point_with_zero_diagonal_is_solved():
    """[[K, Bᵀ], [B, 0]]: the zero pressure diagonal is never a pivot; the answer is COLAMD's."""
    n = 12
    K = laplacian(n) + sp.eye(n * n)
    Bx = sp.random(n * n // 4, n * n, density=0.05, random_state=3, format="csr")
    M = sp.bmat([[K, Bx.T], [Bx, None]]).tocsc()
    b = np.random.default_rng(1).standard_normal(M.shape[0])
    x = factorize(M, SolverStats()).solve(b)
    ref = factorize(M, SolverStats(), "superlu-colamd").solve(b)
    assert np.linalg.norm(M @ x - b) <= 1e-12 * np.linalg.norm(b)
    assert np.linalg.norm(x - ref) <= 1e-10 * np.linalg.norm(ref)


def test_refinement_is_bounded_and_counted():
    """A tolerance below round-off: the direct solve is refined REFINEMENTS times, then returned."""
    A = laplacian(10)
    stats = SolverStats()
    solver = ReusingSolver(stats, "superlu", Reuse("none", tolerance=1e-30))
    x = solver.solve(A, np.ones(100))
    assert stats.refinements == ReusingSolver.REFINEMENTS
    assert np.linalg.norm(A @ x - 1.0) <= 1e-13 * 10.0


def test_a_coupled_run_does_not_depend_on_the_ordering(tmp_path):
    """The quick-start case on a coarse mesh, splitting with Krylov reuse: the two SuperLU orderings give
    the same probes to the solver tolerance and both close the ledger."""
    eta = {}
    for backend in ("superlu", "superlu-colamd"):
        sets = ("mesh.nz=24", "mesh.nr=4", "time.end=0.003", "output.every=0", f"solver.linear={backend}")
        code, summary, rows = run_cli("pulse-koiter-thick", tmp_path / backend, *sets)
        assert code == 0 and summary["status"] == "ok"
        assert summary["energy"]["max_relative_residual"] <= 1e-9
        eta[backend] = np.array([float(r["eta_z1"]) for r in rows])
    a, b = eta["superlu"], eta["superlu-colamd"]
    assert len(a) == 30 and np.max(np.abs(a)) > 0.0
    assert np.max(np.abs(a - b)) <= 1e-11 * np.max(np.abs(a))  # measured 5e-14; GMRES stops at 1e-12
