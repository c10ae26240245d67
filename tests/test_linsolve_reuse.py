"""Solving a changing matrix by GMRES on an earlier factorization (``[solver] reuse``)."""

import doctest

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from runs import run_cli

import multilayer.numerics.krylov
import multilayer.numerics.linsolve
from multilayer.numerics.krylov import SolutionSpan, preconditioned_gmres
from multilayer.numerics.linsolve import Reuse, ReusingSolver, SolverStats


@pytest.mark.parametrize("module", [multilayer.numerics.krylov, multilayer.numerics.linsolve])
def test_doctests(module):
    assert doctest.testmod(module).failed == 0


def drifting_matrices(n=400, steps=6, drift=1e-3, seed=0):
    """A nonsymmetric sparse matrix that changes by ``drift`` (relative) every step."""
    rng = np.random.default_rng(seed)
    base = sp.random(n, n, density=0.01, random_state=seed) + sp.diags(4.0 + rng.random(n))
    change = sp.random(n, n, density=0.01, random_state=seed + 1)
    return [(base + k * drift * change).tocsr() for k in range(steps)]


def test_krylov_answer_is_the_direct_answer_to_the_tolerance():
    stats = SolverStats()
    solver = ReusingSolver(stats, "superlu", Reuse("krylov", 8, 1e-12))
    b = np.random.default_rng(2).standard_normal(400)
    for A in drifting_matrices():
        x = solver.solve(A, b)
        direct = spla.spsolve(A.tocsc(), b)
        assert np.linalg.norm(b - A @ x) <= 1e-12 * np.linalg.norm(b)
        assert np.linalg.norm(x - direct) <= 1e-10 * np.linalg.norm(direct)
    assert stats.factorizations == 1 and stats.krylov_solves == 5
    assert 5 <= stats.krylov_iterations <= 5 * 8


def test_refactorizes_past_the_bound_and_none_factorizes_every_matrix():
    far = drifting_matrices(drift=0.5)
    stats = SolverStats()
    solver = ReusingSolver(stats, "superlu", Reuse("krylov", 2, 1e-12))
    b = np.ones(400)
    for A in far:
        x = solver.solve(A, b)
        assert np.linalg.norm(b - A @ x) <= 1e-12 * np.linalg.norm(b)
    assert stats.factorizations > 1  # GMRES could not reach 1e-12 in 2 iterations on a matrix that far
    none = SolverStats()
    solver = ReusingSolver(none, "superlu", Reuse("none"))
    for A in far:
        solver.solve(A, b)
        solver.solve(A, 2 * b)  # the same matrix again: its own factors
    assert none.factorizations == len(far) and none.krylov_solves == 0 and none.solves == 2 * len(far)


def test_gmres_pays_one_back_substitution_per_iteration_and_an_exhausted_bound_refactorizes_next(monkeypatch):
    """No back-substitution beyond one per GMRES iteration; after a solve that took all max_iterations, the next
    matrix is factorized without trying GMRES (it would fail after paying for them: the drift only grows).
    GMRES starts from 0 here: from the span's guess these matrices need one or two iterations at any age."""
    monkeypatch.setattr(SolutionSpan, "start", lambda self, A, b: None)
    stats = SolverStats()
    solver = ReusingSolver(stats, "superlu", Reuse("krylov", 5, 1e-12))
    b = np.ones(400)
    log = []
    for A in drifting_matrices(drift=0.01, steps=20):
        before = (stats.krylov_iterations, stats.factorizations, stats.solves)
        x = solver.solve(A, b)
        assert np.linalg.norm(b - A @ x) <= 1e-12 * np.linalg.norm(b)
        log.append(tuple(after - b4 for after, b4 in zip((stats.krylov_iterations, stats.factorizations,
                                                           stats.solves), before)))
    for (its, factorizations, solves), following in zip(log, log[1:]):
        if factorizations == 0:
            assert solves == its  # a Krylov solve: its back-substitutions are its iterations
            if its == 5:
                assert following == (0, 1, 1)  # factorized at once, one direct solve
    assert sum(1 for its, f, _ in log[:-1] if f == 0 and its == 5) >= 2, log  # the rule was exercised


def test_factors_that_cost_iterations_are_replaced_at_the_break_even(monkeypatch):
    """Factors that still converge but need more iterations than when they were young: the iterations beyond
    what their first solve's rate would need add up, and at ``factorization_cost`` the next matrix is
    factorized.  GMRES from 0 on matrices drifting by 0.3 % a step (bound 40, never reached): a fresh
    factorization's first solve takes 4 iterations, later ones 5, so with a cost of 4 every factorization
    serves 5 solves (1 + 1 + 1 + 1 extra); by default (400 unknowns: a cost of 14) 10, the later ones at 6
    iterations (1 + 1 + 1 + 1 + 2 × 5 extra); with a cost beyond reach there is one factorization and the
    iterations climb to 8."""
    monkeypatch.setattr(SolutionSpan, "start", lambda self, A, b: None)
    b = np.ones(400)
    runs = {}
    for cost in (4.0, None, 1e9):
        stats = SolverStats()
        solver = ReusingSolver(stats, "superlu", Reuse("krylov", 40, 1e-12, factorization_cost=cost))
        iterations = []
        for A in drifting_matrices(drift=0.003, steps=30):
            before = (stats.krylov_iterations, stats.factorizations)
            x = solver.solve(A, b)
            assert np.linalg.norm(b - A @ x) <= 1e-12 * np.linalg.norm(b)
            iterations.append(-1 if stats.factorizations > before[1] else stats.krylov_iterations - before[0])
        runs[cost] = (stats.factorizations, iterations)
    factorizations, iterations = runs[4.0]
    assert factorizations == 5 and iterations == [-1, 4, 5, 5, 5, 5] * 5, iterations
    assert multilayer.numerics.linsolve.factorization_cost(400) == 14.0
    factorizations, iterations = runs[None]
    assert factorizations == 3 and iterations[:22] == [-1, 4, 5, 5, 5, 5, 6, 6, 6, 6, 6] * 2, iterations
    factorizations, iterations = runs[1e9]
    assert factorizations == 1 and max(iterations) == 8 and sum(iterations) > sum(runs[4.0][1]) + 40


def test_reuse_is_validated():
    with pytest.raises(ValueError, match="reuse mode"):
        Reuse("sometimes")
    with pytest.raises(ValueError, match="max_iterations"):
        Reuse("krylov", 0)
    with pytest.raises(ValueError, match="factorization_cost"):
        Reuse(factorization_cost=0.0)


@pytest.mark.parametrize("coupler, factors", [('{model="kinematic-splitting"}', "double"),
                                              ('{model="monolithic",scheme="bdf2"}', "double"),
                                              ('{model="kinematic-splitting"}', "single"),
                                              ('{model="monolithic",scheme="crank-nicolson"}', "single")])
def test_coupled_run_with_krylov_matches_the_direct_run(tmp_path, coupler, factors):
    """Every series column of the Krylov run (the default; and on single-precision factors) is the refactorized
    double-precision run's to ~the solver tolerance."""
    sets = ("mesh.nz=24", "mesh.nr=4", "time.end=0.004", f"coupler={coupler}")
    _, direct, rows_d = run_cli("pulse-koiter-thick", tmp_path / "direct", *sets, "solver.reuse=none")
    _, krylov, rows_k = run_cli("pulse-koiter-thick", tmp_path / "krylov", *sets, f"solver.factors={factors}")
    assert direct["status"] == krylov["status"] == "ok"
    system = "fluid" if "splitting" in coupler else "monolithic"
    assert krylov["factorizations"][system] < direct["factorizations"][system] == 40
    assert krylov["krylov"][system]["solves"] > 0
    assert krylov["krylov"][system]["factorization_cost"] == 14.0  # the default below 70k unknowns
    assert "fallbacks" not in krylov["krylov"][system]  # single-precision factors sufficed
    for key in ("eta_z1", "eta_z3", "q_in", "kinetic.fluid", "energy.total"):
        d = np.array([float(r[key]) for r in rows_d])
        k = np.array([float(r[key]) for r in rows_k])
        assert np.max(np.abs(k - d)) <= 1e-9 * np.max(np.abs(d)), key
    # every solve of a single-precision run stops at the tolerance (a double run's direct solves go below it)
    assert krylov["energy"]["max_relative_residual"] <= (1e-11 if factors == "double" else 1e-10)


def test_a_matrix_solved_again_is_factorized_once_for_its_further_solves():
    stats = SolverStats()
    solver = ReusingSolver(stats, "superlu", Reuse())
    first, second = drifting_matrices(steps=2)
    solver.solve(first, np.ones(400))
    assert not solver.repeats(second, key="step 2") and solver.repeats(first)
    for k in range(5):  # sub-iterations: one matrix, new right-hand sides
        x = solver.solve(second, np.full(400, k + 1.0), key="step 2")
        assert np.linalg.norm(second @ x - (k + 1.0)) <= 1e-12 * np.sqrt(400) * (k + 1.0)
        assert solver.repeats(second, key="step 2") and not solver.repeats(second)  # the key stands for it
    assert stats.krylov_solves == 1 and stats.factorizations == 2


def test_a_lasting_matrix_is_factorized_at_its_first_solve():
    """A matrix to be solved again (a chord iteration's held tangent) is not first solved by GMRES on older factors:
    its own factorization serves every solve."""
    stats = SolverStats()
    solver = ReusingSolver(stats, "superlu", Reuse())
    first, second = drifting_matrices(steps=2)
    solver.solve(first, np.ones(400))
    for k in range(3):
        x = solver.solve(second, np.full(400, k + 1.0), key="held", lasting=True)
        assert np.linalg.norm(second @ x - (k + 1.0)) <= 1e-12 * np.sqrt(400) * (k + 1.0)
    assert stats.krylov_solves == 0 and stats.factorizations == 2


def test_the_guess_saves_iterations_and_changes_no_answer(monkeypatch):
    """Matrices and right-hand sides drifting smoothly: GMRES started from the span of the solutions gains fewer
    orders than from M⁻¹b, and both reach the tolerance (the answers agree to it)."""
    mats = drifting_matrices(steps=10, drift=1e-3)
    rng = np.random.default_rng(5)
    b0, db = rng.standard_normal(400), rng.standard_normal(400)
    answers, iterations = {}, {}
    for name in ("guess", "no guess"):
        if name == "no guess":
            monkeypatch.setattr(SolutionSpan, "start", lambda self, A, b: None)
        stats = SolverStats()
        solver = ReusingSolver(stats, "superlu", Reuse("krylov", 8, 1e-12))
        xs = []
        for k, A in enumerate(mats):
            b = b0 + 1e-3 * k * db
            xs.append(solver.solve(A, b))
            assert np.linalg.norm(b - A @ xs[-1]) <= 1e-12 * np.linalg.norm(b)
        answers[name], iterations[name] = np.array(xs), stats.krylov_iterations
        assert stats.factorizations == 1
    assert iterations["guess"] < iterations["no guess"]
    assert np.max(np.abs(answers["guess"] - answers["no guess"])) <= 1e-10 * np.max(np.abs(answers["guess"]))


def test_the_guess_is_exact_on_solutions_polynomial_in_the_step():
    """Solutions that are a polynomial of degree < k in the step (k = the span's size) lie in the span of the
    last k: the least-residual guess is the next one, to round-off, for any matrix — also after the ring has
    wrapped (the oldest let go, the columns out of order)."""
    rng = np.random.default_rng(2)
    A = sp.random(60, 60, density=0.1, random_state=rng) + 4.0 * sp.eye(60)
    A = A.tocsr()
    span = SolutionSpan(4)
    assert span.guess(A, np.ones(60)) is None
    for degree, steps in ((0, 1), (1, 2), (3, 4), (2, 11), (3, 9)):
        coefficients = rng.standard_normal((degree + 1, 60))
        f = lambda t: sum(c * t**p for p, c in enumerate(coefficients))  # noqa: E731
        span.clear()
        for t in range(steps):
            span.add(f(t))
        assert len(span) == min(steps, 4)
        x = span.guess(A, A @ f(steps))
        assert np.linalg.norm(x - f(steps)) <= 1e-10 * np.linalg.norm(f(steps)), (degree, steps)


def test_the_guess_minimizes_the_residual_over_the_latest_solutions_only():
    """The guess's residual is at most that of any combination of the span (here the quadratic extrapolation
    and each solution alone); a solution older than the span's size no longer counts, even the exact one."""
    rng = np.random.default_rng(4)
    A = (sp.random(80, 80, density=0.1, random_state=rng) + 5.0 * sp.eye(80)).tocsr()
    b = rng.standard_normal(80)
    span = SolutionSpan(3)
    exact = spla.spsolve(A.tocsc(), b)
    span.add(exact)
    assert np.linalg.norm(A @ span.guess(A, b) - b) <= 1e-12 * np.linalg.norm(b)
    xs = [rng.standard_normal(80) for _ in range(3)]
    for x in xs:
        span.add(x)  # the exact solution is let go
    r = np.linalg.norm(b - A @ span.guess(A, b))
    assert r > 1e-3 * np.linalg.norm(b)
    for combination in (3 * xs[2] - 3 * xs[1] + xs[0], *xs):
        assert r <= np.linalg.norm(b - A @ combination) * (1 + 1e-12)
    span.add(np.ones(81))  # a system of another size starts the span afresh
    assert len(span) == 1 and span.guess(A, b) is None
    with pytest.raises(ValueError, match="at least 1"):
        SolutionSpan(0)


def test_the_start_carries_the_guess_residual_and_gmres_from_it_gives_the_same_answer():
    """SolutionSpan.start's r₀ (from the least-squares product A X) is b − A x₀ to round-off, and GMRES handed
    it stops at the same iteration with the same answer as GMRES forming b − A x₀ itself."""
    rng = np.random.default_rng(7)
    A0 = (sp.random(120, 120, density=0.08, random_state=rng) + 6.0 * sp.eye(120)).tocsr()
    lu = spla.splu(A0.tocsc())
    span = SolutionSpan(5)
    for k in range(7):
        Ak = (A0 + 0.02 * k * sp.diags(np.cos(np.arange(120.0) + k))).tocsr()
        b = np.sin(0.1 * np.arange(120) + 0.3 * k)
        start = span.start(Ak, b)
        if start is not None:
            x0, r0 = start
            assert np.array_equal(x0, span.guess(Ak, b))
            assert np.linalg.norm(r0 - (b - Ak @ x0)) <= 1e-14 * np.linalg.norm(b)
            given, its_given, *_ = preconditioned_gmres(Ak, b, lu.solve, 1e-12, 20, x0, residual=r0)
            formed, its_formed, *_ = preconditioned_gmres(Ak, b, lu.solve, 1e-12, 20, x0)
            assert its_given == its_formed >= 1
            assert np.linalg.norm(given - formed) <= 1e-11 * np.linalg.norm(formed)
            assert np.linalg.norm(b - Ak @ given) <= 1e-12 * np.linalg.norm(b)
        span.add(spla.spsolve(Ak.tocsc(), b))
    assert len(span) == 5


def test_single_precision_factors_give_the_double_answer():
    """GMRES–IR: float32 factors, float64 residuals: the same tolerance, so the double run's answer to it, with
    and without reuse; every solve of a single-precision run is a Krylov solve."""
    b = np.random.default_rng(3).standard_normal(400)
    answers = {}
    for mode in ("krylov", "none"):
        for factors in ("double", "single"):
            stats = SolverStats()
            solver = ReusingSolver(stats, "superlu", Reuse(mode, 8, 1e-12, factors))
            xs = []
            for A in drifting_matrices(steps=8, drift=1e-2):
                xs.append(solver.solve(A, b))
                assert np.linalg.norm(b - A @ xs[-1]) <= 1e-12 * np.linalg.norm(b)
            answers[mode, factors] = np.array(xs)
            assert stats.fallbacks == 0
            if factors == "single":
                assert stats.krylov_solves == 8 and stats.refinements == 0
    for key, x in answers.items():
        assert np.max(np.abs(x - answers["none", "double"])) <= 1e-10 * np.max(np.abs(x)), key


def test_single_precision_factors_that_do_not_serve_fall_back_to_double():
    """Float32 factors that do not exist (entries beyond float32's range) or that GMRES cannot converge from
    within max_iterations (2×2 blocks [[1, 1], [1, 1 + δ]] with δ near float32's resolution: every block's
    small pivot off by up to ~100 %): the matrix is factorized in double, the answer reaches the tolerance,
    the fallback is counted, and the solver stays double."""
    big = (drifting_matrices()[0] * 1e40).tocsr()
    d = np.logspace(-6.8, -6.0, 200)
    blocks = sp.block_diag([sp.csr_matrix(np.array([[1.0, 1.0], [1.0, 1.0 + dk]])) for dk in d]).tocsr()
    rng = np.random.default_rng(4)
    for A, bound, factorizations in ((big, 8, 1), (blocks, 2, 2)):
        b = A @ rng.standard_normal(A.shape[0])
        stats = SolverStats()
        solver = ReusingSolver(stats, "superlu", Reuse("krylov", bound, 1e-12, "single"))
        x = solver.solve(A, b)
        assert np.linalg.norm(b - A @ x) <= 1e-12 * np.linalg.norm(b)
        assert stats.fallbacks == 1 and stats.factorizations == factorizations  # (a singular one is not counted)
        again = solver.factorize(A)  # a later factorization is double: its direct solve meets the tolerance
        assert np.linalg.norm(b - A @ again.solve(b)) <= 1e-12 * np.linalg.norm(b)
        assert stats.fallbacks == 1 and stats.factorizations == factorizations + 1


def test_single_precision_factors_need_a_superlu_backend(monkeypatch):
    monkeypatch.setitem(multilayer.numerics.linsolve.BACKENDS, "other", lambda: (lambda A: None))
    with pytest.raises(ValueError, match="single-precision factors need one of the linear solvers"):
        multilayer.numerics.linsolve.factorize(sp.eye(3).tocsc(), SolverStats(), "other", single=True)
    with pytest.raises(ValueError, match="factors 'half'"):
        Reuse(factors="half")
