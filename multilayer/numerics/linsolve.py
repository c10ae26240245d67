"""Sparse direct solvers behind one small interface, with factorization counting.

A :class:`Factorized` is what a step needs: ``solve(b)``.  Backends are looked
up by name; ``"superlu"`` (scipy's SuperLU on a METIS nested-dissection
ordering kept per sparsity pattern) and ``"superlu-colamd"`` (SuperLU's own
COLAMD ordering, redone each time) are always there, ``"pardiso"`` (MKL
PARDISO through pypardiso, the optional extra ``fast``) when that is
installed.  Every
factorization is counted and timed on the :class:`SolverStats` passed in, so a
run can prove that a matrix which never changes was factorized once.

A matrix that changes a little every step (the fluid's Oseen matrix, the
monolithic system) is solved by a :class:`ReusingSolver`: GMRES
preconditioned by the factorization of an earlier step's matrix, which is
refactorized only when GMRES needs more than a bound of iterations
(:class:`Reuse`, ``[solver] reuse``; :mod:`multilayer.numerics.krylov`).
"""

from __future__ import annotations

import importlib.util
import math
import time
from collections.abc import Callable

import attrs
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from multilayer.numerics.held import held, kept, matrix_of
from multilayer.numerics.krylov import (
    GMRESResult,
    SolutionSpan,
    Workspace,
    preconditioned_gmres,
)
from multilayer.numerics.ordering import nested_dissection, pattern_key
from multilayer.numerics.pardiso import Pardiso


@attrs.define
class SolverStats:
    """Counts and seconds of factorizations and solves.

    ``solves`` counts back-substitutions with a factorization (also those a
    Krylov solve uses as its preconditioner); ``krylov_solves`` the systems
    solved by a preconditioned Krylov method and ``krylov_iterations`` their
    iterations (one matrix–vector product and one back-substitution each);
    ``krylov_s`` the seconds of those solves (their back-substitutions
    included, so they are also in ``solve_s``).
    """

    factorizations: int = 0
    solves: int = 0
    factorization_s: float = 0.0
    solve_s: float = 0.0
    krylov_solves: int = 0
    krylov_iterations: int = 0
    krylov_s: float = 0.0
    #: iterative-refinement sweeps after direct solves (:meth:`ReusingSolver.solve`)
    refinements: int = 0
    #: single-precision factorizations that did not serve (singular in float32, or GMRES could not converge
    #: from them), replaced by double ones for the rest of the run (``[solver] factors = "single"``)
    fallbacks: int = 0
    #: the price of a factorization in GMRES iterations that :class:`ReusingSolver` refactorizes at (the
    #: case's ``factorization_cost``, or :func:`factorization_cost` of the system's size); None before any
    factorization_cost: float | None = None
    #: Newton solves of a nonlinear system (:func:`multilayer.numerics.newton.newton`; none for a linear one),
    #: their corrections in all, the most one took, the largest relative residual one ended at and the last's
    newton_solves: int = 0
    newton_iterations: int = 0
    newton_max_iterations: int = 0
    newton_residual: float = 0.0
    newton_last_residual: float = 0.0
    #: the :class:`ReusingSolver` counting here (the latest made with these stats), whose held state
    #: (:meth:`ReusingSolver.held`) a checkpoint keeps; and the held state a resumed run hands it to take back
    #: before its first solve, so the run goes on as if it had never stopped
    solver: ReusingSolver | None = attrs.field(default=None, repr=False, eq=False)
    resume: dict | None = attrs.field(default=None, repr=False, eq=False)
    #: the backend instances of this owner, by name: what a backend keeps between factorizations (PARDISO's
    #: symbolic analysis) belongs to one run's solver, never to the process, so runs sharing a worker share nothing
    backends: dict = attrs.field(factory=dict, repr=False, eq=False)


class Factorized:
    """A factorized matrix: ``solve(b)`` (b of one or several columns)."""

    def __init__(self, solve: Callable[[np.ndarray], np.ndarray], stats: SolverStats):
        self._solve = solve
        self._stats = stats

    def solve(self, b: np.ndarray) -> np.ndarray:
        t0 = time.perf_counter()
        x = self._solve(b)
        self._stats.solves += 1
        self._stats.solve_s += time.perf_counter() - t0
        return x


class _SuperLU:
    """scipy's SuperLU on a nested-dissection ordering kept per sparsity pattern.

    The symmetric permutation P of :func:`multilayer.numerics.ordering.nested_dissection`
    is computed at the first factorization of a pattern and reused (``keep``
    patterns are remembered), with where each entry of P A Pᵀ (in CSC) comes
    from in A's data: a later matrix of the pattern is permuted by one gather.
    SuperLU then factorizes P A Pᵀ in its own order (``NATURAL``, symmetric
    mode) with threshold pivoting that keeps a diagonal pivot unless it is
    below ``PIVOT_THRESHOLD`` × the largest entry of its column — the zero
    pressure diagonal of a saddle-point system is never taken, a diagonal
    made nonzero by the elimination usually is.
    """

    keep = 4  #: patterns whose ordering is kept
    PIVOT_THRESHOLD = 1e-3

    def __init__(self) -> None:
        self._orderings: dict[tuple, tuple] = {}

    def __call__(self, A: sp.spmatrix, single: bool = False) -> Callable[[np.ndarray], np.ndarray]:
        if A.format not in ("csr", "csc"):
            A = sp.csc_matrix(A)
        key = pattern_key(A)  # (sorts A's indices in place)
        ordering = self._orderings.get(key)
        if ordering is None:
            ordering = self._orderings[key] = self._ordering(A)
            while len(self._orderings) > self.keep:
                self._orderings.pop(next(iter(self._orderings)))
        perm, take, indices, indptr = ordering
        dtype = np.float32 if single else A.data.dtype
        with np.errstate(over="ignore"):  # an entry beyond float32's range becomes inf: SuperLU finds it singular
            data = A.data[take].astype(dtype, copy=False)
        permuted = sp.csc_matrix((data, indices, indptr), shape=A.shape)
        lu = spla.splu(permuted, permc_spec="NATURAL", diag_pivot_thresh=self.PIVOT_THRESHOLD,
                       options={"SymmetricMode": True})

        def solve(b: np.ndarray) -> np.ndarray:
            b = np.asarray(b)
            y = lu.solve(np.ascontiguousarray(b[perm], dtype=dtype))
            x = np.empty(y.shape, dtype=np.result_type(b.dtype, np.float64))
            x[perm] = y
            return x

        return solve

    @staticmethod
    def _ordering(A: sp.csr_matrix | sp.csc_matrix) -> tuple:
        """(P, the gather of P A Pᵀ's CSC data from A's, its indices, its indptr) for A's pattern."""
        perm = nested_dissection(A)
        # the positions of A's entries (+1, so that no position is a zero a conversion could drop), permuted
        positions = type(A)((np.arange(1.0, A.nnz + 1.0), A.indices, A.indptr), shape=A.shape)
        P = positions[perm][:, perm].tocsc()
        P.sort_indices()  # canonical, so that nothing downstream sorts the kept indices in place
        dtype = np.int32 if A.nnz < np.iinfo(np.int32).max else np.int64
        kept = (P.data - 1.0).astype(dtype), P.indices, P.indptr
        for a in kept:
            a.flags.writeable = False  # shared by every matrix of the pattern
        return (perm, *kept)


class _SuperLUColamd:
    """scipy's SuperLU with its default column ordering (COLAMD, redone at every factorization).

    What ``"superlu"`` was before the nested-dissection ordering; kept as a
    backend so the two can be measured side by side
    (``--vary solver.linear=superlu,superlu-colamd``).
    """

    def __call__(self, A: sp.spmatrix, single: bool = False) -> Callable[[np.ndarray], np.ndarray]:
        if not single:
            return spla.splu(sp.csc_matrix(A), permc_spec="COLAMD").solve
        with np.errstate(over="ignore"):
            A = sp.csc_matrix(A, dtype=np.float32)
        lu = spla.splu(A, permc_spec="COLAMD")
        return lambda b: lu.solve(np.asarray(b, dtype=np.float32)).astype(np.float64)


Backend = Callable[[sp.spmatrix], Callable[[np.ndarray], np.ndarray]]

OPTIONAL = {"pardiso": ("pypardiso", Pardiso)}  #: name → (module it needs, backend class)

#: name → backend class; :func:`factorize` makes one instance per :class:`SolverStats` (per solver of a run)
BACKENDS: dict[str, Callable[[], Backend]] = {
    "superlu": _SuperLU,
    "superlu-colamd": _SuperLUColamd,
    **{name: backend for name, (module, backend) in OPTIONAL.items() if importlib.util.find_spec(module)},
}
#: the backends that factorize in single precision too (``single=True``)
SINGLE = ("superlu", "superlu-colamd")
#: precisions of the factors a ReusingSolver preconditions with (``[solver] factors``)
FACTORS = ("double", "single")


def factorize(A: sp.spmatrix, stats: SolverStats, backend: str = "superlu", single: bool = False) -> Factorized:
    """Factorize ``A`` with ``backend``, counting it on ``stats``; with ``single`` in float32.

    Single-precision factors solve to ~1e-7 relative accuracy (times the
    condition number): they serve as a preconditioner whose residuals are
    taken in double precision (GMRES–IR, :class:`ReusingSolver`), not as a
    direct solve.  Only the SuperLU backends have them.

    The backend instance is ``stats``'s own (made on its first use), so
    nothing a backend keeps is shared between the solvers of a run or
    between runs in one process.

    >>> st = SolverStats()
    >>> f = factorize(sp.eye(3).tocsc() * 2.0, st)
    >>> f.solve(np.ones(3)), st.factorizations
    (array([0.5, 0.5, 0.5]), 1)
    >>> st.backends["superlu"] is SolverStats().backends.get("superlu")
    False
    """
    if backend not in BACKENDS:
        if backend in OPTIONAL:
            raise KeyError(f"linear solver {backend!r} is not installed (it needs {OPTIONAL[backend][0]}): "
                           f"pip install 'multilayer[fast]'; available: {sorted(BACKENDS)}")
        raise KeyError(f"unknown linear solver {backend!r}; available: {sorted(BACKENDS)}")
    if single and backend not in SINGLE:
        raise ValueError(f"single-precision factors need one of the linear solvers {list(SINGLE)}, not {backend!r}")
    t0 = time.perf_counter()
    if backend not in stats.backends:
        stats.backends[backend] = BACKENDS[backend]()
    solve = stats.backends[backend](A, single=True) if single else stats.backends[backend](A)
    stats.factorizations += 1
    stats.factorization_s += time.perf_counter() - t0
    return Factorized(solve, stats)


# -- reuse of an earlier factorization ------------------------------------------
REUSE_MODES = ("krylov", "none")


@attrs.frozen
class Reuse:
    """When a changing matrix is refactorized (``[solver] reuse``, ``max_iterations``, ``tolerance``).

    Attributes
    ----------
    mode : str
        ``"krylov"``: solve with GMRES preconditioned by the factorization of
        an earlier matrix; ``"none"``: factorize every new matrix.
    max_iterations : int
        GMRES iterations above which the preconditioner is refactorized: a
        solve that needs more is redone with a fresh factorization of its own
        matrix, which then preconditions the following steps; a solve that
        needed all of them is followed by a fresh factorization at once (the
        drift only grows, so the next solve would fail after paying for them).
    tolerance : float
        Relative residual ‖b − A x‖₂ ≤ tolerance · ‖b‖₂ a Krylov solve must
        reach (checked on the true residual).  The default 1e-12 keeps every
        energy ledger within 1e-11 of round-off closure (docs/performance.md,
        "The tolerance").
    factors : str
        ``"double"``: factorizations in float64, and the matrix just
        factorized solved directly; ``"single"``: in float32 (half their
        memory, faster to make and to apply), every solve by GMRES on them
        with residuals in float64 — the same tolerance, so the same answer
        to it (GMRES–IR).  Where single-precision factors of a matrix are
        too inaccurate for GMRES to converge from, that matrix is factorized
        in double and the solver stays double for the rest of the run
        (counted in ``fallbacks``).
    factorization_cost : float or None
        What a factorization costs, in GMRES iterations: the held factors
        are replaced once the iterations they cost beyond what they needed
        when young add up to this (the break-even rule of renting against
        buying; see :class:`ReusingSolver`).  A very large value leaves
        only ``max_iterations``.  None (the default): :func:`factorization_cost`
        of the matrix's size.
    """

    mode: str = "krylov"
    max_iterations: int = 8
    tolerance: float = 1e-12
    factors: str = "double"
    factorization_cost: float | None = None

    def __attrs_post_init__(self):
        if self.mode not in REUSE_MODES:
            raise ValueError(f"reuse mode {self.mode!r} is not one of {REUSE_MODES}")
        if self.max_iterations < 1:
            raise ValueError(f"max_iterations must be ≥ 1, got {self.max_iterations!r}")
        if not 0.0 < self.tolerance < 1.0:
            raise ValueError(f"tolerance must be in (0, 1), got {self.tolerance!r}")
        if self.factors not in FACTORS:
            raise ValueError(f"factors {self.factors!r} is not one of {FACTORS}")
        if self.factorization_cost is not None and not self.factorization_cost > 0.0:
            raise ValueError(f"factorization_cost must be > 0 (GMRES iterations), got {self.factorization_cost!r}")


def factorization_cost(n: int) -> float:
    """A fresh factorization of an n-unknown system, in GMRES iterations: 14 up to 70k unknowns, then ∝ √n.

    Measured on this project's machines for the fluid's Navier–Stokes system
    in a coupled run (the factorization against a GMRES iteration with its
    share of the guess, `benchmarks/scaling.py`): 13–15 at 18k unknowns,
    16–17 at 69k, 26–27 at 277k, 48–55 at 1.11M (docs/performance.md, "When
    to refactorize").  A nested-dissection factorization of a 2D mesh grows
    like n^1.5 and a back-substitution like n log n; over this range the
    measured ratio grows like √n above 70k.

    >>> factorization_cost(20_000), round(factorization_cost(1_120_000))
    (14.0, 56)
    """
    return 14.0 * max(1.0, n / 70_000) ** 0.5


@attrs.frozen(eq=False)
class LowRank:
    """A low-rank term U Wᵀ (U, W of shape n × k, k small) added to a sparse matrix: the exact Jacobian of a
    force whose derivative has a dense rank-k part (Crank–Nicolson's discrete gradient,
    :func:`multilayer.coupling.structure.step_force`).

    >>> A = sp.diags([2.0, 4.0]).tocsc()
    >>> update = LowRank(np.array([[1.0], [1.0]]), np.array([[1.0], [0.0]]))
    >>> x = update.solver(factorize(A, SolverStats()).solve)(np.array([3.0, 5.0]))
    >>> bool(np.allclose(update.on(A) @ x, [3.0, 5.0]))
    True
    """

    U: np.ndarray
    W: np.ndarray

    def on(self, A: sp.spmatrix) -> Updated:
        """A + U Wᵀ as an operator (products only)."""
        return Updated(A, self)

    def solver(self, solve: Callable[[np.ndarray], np.ndarray]) -> Callable[[np.ndarray], np.ndarray]:
        """b ↦ (A + U Wᵀ)⁻¹ b from ``solve`` = A⁻¹ (Woodbury: A⁻¹b − A⁻¹U (I + Wᵀ A⁻¹U)⁻¹ Wᵀ A⁻¹b), A⁻¹U
        solved once."""
        AU = solve(self.U)
        AU = AU.reshape(self.U.shape)
        capacitance = np.eye(self.U.shape[1]) + self.W.T @ AU

        def updated(b: np.ndarray) -> np.ndarray:
            y = solve(b)
            return y - AU @ np.linalg.solve(capacitance, self.W.T @ y)

        return updated


@attrs.frozen(eq=False)
class Updated:
    """A sparse matrix plus a :class:`LowRank` term, as far as GMRES and a residual use it: ``@`` and ``shape``."""

    A: sp.spmatrix
    update: LowRank

    @property
    def shape(self) -> tuple[int, int]:
        return self.A.shape

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        return self.A @ x + self.update.U @ (self.update.W.T @ x)


class ReusingSolver:
    """Solves A x = b for a sequence of matrices of one size, refactorizing only when needed.

    With ``reuse.mode == "none"`` every new matrix is factorized (a matrix
    passed again as the same object reuses its own factorization).  With
    ``"krylov"`` a new matrix is solved by right-preconditioned GMRES with the
    held factorization (:func:`multilayer.numerics.krylov.preconditioned_gmres`),
    started from the least-residual combination of the latest new matrices'
    solutions (:class:`multilayer.numerics.krylov.SolutionSpan`, ``GUESS_SPAN`` of
    them); when that does not reach the tolerance within
    ``max_iterations`` the matrix is factorized and solved with its own
    factors (directly; by GMRES on them when they are single precision), and
    its factorization is held instead.
    After a solve that took all ``max_iterations``, the next new matrix is
    factorized without trying GMRES first.

    Factors that still converge can still be worth replacing: on the
    quick-start case at 22k unknowns, GMRES on the factors of step 30 needs
    5 iterations at step 45, 4 at step 70 and 3 at step 89, where the
    factors of the step before need 3, 2 and 1 — a few iterations a step,
    for as long as the run goes on, and the bound never sees it.  So the solver
    measures how well its factors fit.  The first Krylov solve with a
    factorization (on the next new matrix) gives its rate, the orders of
    magnitude λ = log₁₀(‖r₀‖/‖r‖)/k each of its k iterations gained.  Every later
    one is compared with what that rate would need for its own start,
    ⌈log₁₀(‖r₀‖/(tol ‖b‖))/λ⌉ iterations; the iterations beyond it add up,
    and when the sum reaches ``reuse.factorization_cost`` — a
    factorization's price in GMRES iterations (:func:`factorization_cost`
    of the size unless the case sets it) — the next new matrix is
    factorized.  This is the break-even rule of renting against buying:
    where a factor's extra iterations only grow with its age it pays at
    most about twice what the best schedule in hindsight would, and it needs
    no guess of how long the run lasts (replaying the
    quick-start case's systems at 22k unknowns: 10 % above that best
    schedule, where the bound alone is 22 % above it; docs/performance.md,
    "When to refactorize").  It uses counts and residual norms only, never
    a clock, so two runs of one case refactorize at the same steps.

    A matrix solved again right after (the same ``key``: the sub-iterations of
    an implicit partitioned coupler) is factorized at its second solve, so
    its further solves are back-substitutions.

    Parameters
    ----------
    stats : SolverStats
        Where factorizations, solves and Krylov iterations are counted.
    backend : str
        A backend of :data:`BACKENDS`.
    reuse : Reuse
        The policy.

    Examples
    --------
    >>> A = sp.diags([4.0, 5.0, 6.0]).tocsr()
    >>> st = SolverStats()
    >>> solver = ReusingSolver(st, "superlu", Reuse())
    >>> x = solver.solve(A, np.ones(3))
    >>> x = solver.solve(A * 1.001, np.ones(3))     # a nearby matrix: GMRES on the old factors
    >>> bool(np.allclose(A * 1.001 @ x, 1.0, rtol=1e-12)), st.factorizations, st.krylov_solves
    (True, 1, 1)
    """

    REFINEMENTS = 3  #: iterative-refinement sweeps at most after a direct solve
    #: the latest new matrices' solutions whose span GMRES starts from.  On the quick-start case at 22k unknowns
    #: the median residual of the guess is 9.9e-6, 8.4e-9, 1.1e-9 and 8.4e-10 with 4, 8, 12 and 16 of them
    #: (1.3e-4 for the quadratic extrapolation), and replaying the run's systems 4.32, 3.93 and 3.71 GMRES
    #: iterations a step with 8, 12 and 16: past 8 the products cost about what they save
    #: (docs/performance.md, "The guess")
    GUESS_SPAN = 8

    def __init__(self, stats: SolverStats, backend: str = "superlu", reuse: Reuse = Reuse()):
        self.stats, self.backend, self.reuse = stats, backend, reuse
        self._matrix = None  # the matrix whose factorization is held
        self.last: sp.spmatrix | None = None  #: the latest matrix solved (benchmarks factorize it afresh)
        self._last_key = None
        self._factors: Factorized | None = None
        self._span = SolutionSpan(self.GUESS_SPAN)  # the latest new matrices' solutions: where GMRES starts
        self._rate: float | None = None  # orders of magnitude a GMRES iteration gained with the held factors young
        #: GMRES iterations the held factors cost beyond that rate's (inf after a solve that needed all of them)
        self._excess = 0.0
        self._workspace = Workspace()  # GMRES's basis, kept: no fresh pages per step
        self._single = reuse.factors == "single"  # until a fallback
        #: the matrix the held factors are of (its data copied: a caller may refill its buffer) and their precision
        self._factored: tuple[sp.spmatrix, bool] | None = None
        stats.solver = self

    def factorize(self, A: sp.spmatrix, key=None) -> Factorized:
        """Factorize ``A`` and hold it (under ``key``, by default A) as the preconditioner of the next solves.

        The factors held until now are let go first: the two never live together.
        """
        self._factors = self._matrix = self._factored = None  # a large mesh's factors are most of its memory
        single = False
        if self._single:
            try:
                self._factors = factorize(A, self.stats, self.backend, single=True)
                single = True
            except RuntimeError:  # singular in float32: an entry beyond its range, a pivot rounded to zero
                self._fall_back()
        if self._factors is None:
            self._factors = factorize(A, self.stats, self.backend)
        self._factored = (kept(A), single)
        self._matrix = A if key is None else key
        self._shape = A.shape
        self._rate, self._excess = None, 0.0
        cost = self.reuse.factorization_cost
        self.stats.factorization_cost = factorization_cost(A.shape[0]) if cost is None else cost
        return self._factors

    def held(self) -> dict:
        """What the solver holds between two steps, as data (:func:`multilayer.numerics.held.held`)."""
        return held(self)

    def restore(self, state: dict) -> None:
        """Take back what :meth:`held` gave (checked by :func:`multilayer.numerics.held.check`): the matrix
        factorized again in its precision, the counters, the span; the next solve is the one of the run it is from."""
        self._factors = self._matrix = self._factored = None
        self._last_key = self.last = None
        self._single = self.reuse.factors == "single" and not state["double_only"]
        if (held_matrix := matrix_of(state)) is not None:
            A, single = held_matrix
            self._factors = factorize(A, self.stats, self.backend, single=single)
            self._factored, self._shape = (A, single), A.shape
            self._matrix = object()  # no later matrix is this one: the next is new, as it was in the run
        self._rate, self._excess = state["rate"], state["excess"]
        self.stats.factorization_cost = state["factorization_cost"]
        self._span.restore(state["span"], state["count"])

    def repeats(self, A: sp.spmatrix, key=None) -> bool:
        """True when ``A`` (``key`` standing for it) is the matrix solved just before: a sub-iteration's matrix,
        not a new one (its solution does not enter the span of new matrices' solutions)."""
        return self._last_key is (A if key is None else key)

    def holds(self, key) -> bool:
        """True when the held factorization is of the matrix ``key`` stands for (compared by identity)."""
        return self._factors is not None and self._matrix is key

    def solve(self, A: sp.spmatrix, b: np.ndarray, key=None, update: LowRank | None = None,
              lasting: bool = False) -> np.ndarray:
        """x with A x = b: directly when the factors are A's, else by GMRES on the held ones or a fresh LU.

        ``key`` stands for A when A is rebuilt from data that did not change (e.g. the token of the system it
        is a block of); by default A itself.  With ``update`` the system is (A + U Wᵀ) x = b: the factors are
        always of the sparse A, GMRES takes the whole operator, and a direct solve with A's own factors adds
        the update by Woodbury's formula (:class:`LowRank`), so a dense low-rank term never enters a
        factorization.  A ``lasting`` A is to be solved again (a chord iteration's held tangent): factorized
        at its first solve, not after a GMRES one.
        """
        key = A if key is None else key
        if self.stats.resume is not None:  # a resumed run: the held state of the checkpoint first
            held, self.stats.resume = self.stats.resume, None
            self.restore(held)
        again = self.repeats(A, key)
        self._last_key, self.last = key, A
        operator = A if update is None else update.on(A)
        if self.holds(key):
            return self._refined(operator, b, update)
        x = None
        # a matrix solved a second time (a sub-iterated coupler) is worth its own factorization
        if (self.reuse.mode == "krylov" and not again and not lasting and self._factors is not None
                and A.shape == self._shape and not self._stale()):
            result = self._gmres(operator, b, guess=True)
            x = result.x
            if x is not None:
                self._weigh(result, b)
            if result.iterations >= self.reuse.max_iterations:  # the drift only grows: the next would fail too
                self._excess = math.inf
        if x is None:
            self.factorize(A, key)
            x = self._refined(operator, b, update)
        if not again:
            self._span.add(x)
        return x

    def _gmres(self, A: sp.spmatrix, b: np.ndarray, guess: bool) -> GMRESResult:
        """GMRES on the held factors (from the span's guess if ``guess``, else 0), counted (iterations, seconds
        with the guess's, solves that converged)."""
        t0 = time.perf_counter()
        x0, r0 = (self._span.start(A, b) if guess else None) or (None, None)
        result = preconditioned_gmres(A, b, self._factors.solve, self.reuse.tolerance, self.reuse.max_iterations,
                                      x0, self._workspace, r0)
        self.stats.krylov_iterations += result.iterations
        self.stats.krylov_s += time.perf_counter() - t0
        if result.x is not None:
            self.stats.krylov_solves += 1
        return result

    def _weigh(self, result: GMRESResult, b: np.ndarray) -> None:
        """Add what a converged Krylov solve of a new matrix says about the held factors (see the class doc).

        The first solve with them sets the rate λ (orders of magnitude an
        iteration); each later one adds its iterations beyond
        ⌈log₁₀(‖r₀‖/(tol ‖b‖))/λ⌉ (at least 1: GMRES always does one) to
        the excess.
        """
        if not (result.start > 0.0 and result.end > 0.0):  # b = 0, or an exact start: nothing to learn
            return
        if self._rate is None:
            self._rate = max(np.log10(result.start / result.end), 1e-3) / result.iterations
            return
        needed = np.log10(result.start / (self.reuse.tolerance * np.linalg.norm(b)))
        expected = max(1, int(np.ceil(needed / self._rate - 1e-9)))
        self._excess += max(result.iterations - expected, 0)

    def _stale(self) -> bool:
        """Whether the held factors have cost, beyond their young rate, what a fresh factorization costs
        (or took all ``max_iterations`` in their latest solve)."""
        return self._excess >= self.stats.factorization_cost

    def _fall_back(self) -> None:
        """From now on, double-precision factors (single ones did not serve: counted in ``fallbacks``)."""
        self._single = False
        self.stats.fallbacks += 1

    def _refined(self, A, b: np.ndarray, update: LowRank | None = None) -> np.ndarray:
        """The held factors' solution of A x = b, to ‖b − A x‖ ≤ tolerance ‖b‖.

        Double-precision factors: a direct solve, with iterative refinement
        while the residual is above the tolerance (a factorization with
        threshold pivoting — the SuperLU backend keeps small diagonal pivots —
        may leave one); each sweep costs one product and one
        back-substitution, and is counted in ``refinements``; at most
        ``REFINEMENTS`` sweeps.  With a low-rank ``update`` (``A`` its operator) each solve adds it
        by Woodbury's formula.  Single-precision factors: GMRES on them
        (counted as a Krylov solve); where it does not converge within
        ``max_iterations`` the matrix is factorized in double precision, and
        the solver stays double for the rest of the run (a ``fallback``).
        """
        if self._single:
            x = self._gmres(A, b, guess=False).x
            if x is not None:
                return x
            self._fall_back()
            self.factorize(A if update is None else A.A, self._matrix)
        solve = self._factors.solve if update is None else update.solver(self._factors.solve)
        x = solve(b)
        target = self.reuse.tolerance * np.linalg.norm(b)
        for _ in range(self.REFINEMENTS):
            r = b - A @ x
            if not np.linalg.norm(r) > target:
                break
            x = x + solve(r)
            self.stats.refinements += 1
        return x
