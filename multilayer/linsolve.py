"""Sparse direct solvers behind one small interface, with factorization counting.

A :class:`Factorized` is what a step needs: ``solve(b)``.  Backends are looked
up by name; ``"superlu"`` (scipy) is always there, ``"pardiso"`` (MKL PARDISO
through pypardiso, the optional extra ``fast``) when that is installed.  Every
factorization is counted and timed on the :class:`SolverStats` passed in, so a
run can prove that a matrix which never changes was factorized once.
"""

from __future__ import annotations

import hashlib
import importlib.util
import time
from collections.abc import Callable

import attrs
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


@attrs.define
class SolverStats:
    """Counts and seconds of factorizations and solves."""

    factorizations: int = 0
    solves: int = 0
    factorization_s: float = 0.0
    solve_s: float = 0.0
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
    """scipy's SuperLU (COLAMD ordering); keeps nothing between factorizations."""

    def __call__(self, A: sp.spmatrix) -> Callable[[np.ndarray], np.ndarray]:
        return spla.splu(sp.csc_matrix(A), permc_spec="COLAMD").solve


def _pypardiso():
    try:
        import pypardiso
    except ImportError as exc:  # registered, but it (or MKL's runtime) did not load
        raise RuntimeError(f"linear solver 'pardiso' needs pypardiso: pip install 'multilayer[fast]' ({exc})") from exc
    return pypardiso


class _Pardiso:
    """MKL PARDISO (real unsymmetric; METIS ordering, matching, parallel factorization).

    The symbolic analysis (phase 11: ordering and symbolic factorization) is
    kept per sparsity pattern and only the numeric factorization (phase 22)
    is redone for a new matrix of that pattern: the fluid's pattern is fixed
    for a run, so only its first factorization pays for the ordering.  One
    PARDISO handle holds the numeric factors of the latest matrix of each
    pattern; a ``solve`` of an older matrix of the same pattern refactorizes
    that matrix first, so every ``solve`` stays the solve of its own matrix.

    pypardiso's public ``factorize`` always reorders, so the phases are run
    through its ``_call_pardiso`` (hence the extra pins ``pypardiso<0.5``).
    """

    keep = 4  #: patterns whose analysis is kept; the oldest is released beyond that

    def __init__(self) -> None:
        self._handles: dict[tuple, object] = {}  # pattern → PyPardisoSolver
        self._holds: dict[tuple, sp.csr_matrix] = {}  # pattern → the matrix its numeric factors are of

    def __call__(self, A: sp.spmatrix) -> Callable[[np.ndarray], np.ndarray]:
        A = sp.csr_matrix(A, dtype=float, copy=True)
        A.sort_indices()
        key = (A.shape[0], hashlib.sha1(A.indptr).digest(), hashlib.sha1(A.indices).digest())
        self._factorize(key, A)

        def solve(b: np.ndarray) -> np.ndarray:
            if self._holds.get(key) is not A:
                self._factorize(key, A)
            handle = self._handles[key]
            handle.set_phase(33)
            return handle._call_pardiso(A, handle._check_b(A, np.asarray(b, dtype=float)))

        return solve

    def _factorize(self, key: tuple, A: sp.csr_matrix) -> None:
        handle = self._handles.get(key)
        if handle is None:
            handle = _pypardiso().PyPardisoSolver()
            handle._check_A(A)
            self._pardiso(handle, 11, A)
            self._handles[key] = handle
            while len(self._handles) > self.keep:
                old = next(iter(self._handles))
                self._handles.pop(old).free_memory(everything=True)
                self._holds.pop(old, None)
        self._pardiso(handle, 22, A)
        self._holds[key] = A

    @staticmethod
    def _pardiso(handle, phase: int, A: sp.csr_matrix) -> None:
        handle.set_phase(phase)
        handle._call_pardiso(A, np.zeros((A.shape[0], 1)))


Backend = Callable[[sp.spmatrix], Callable[[np.ndarray], np.ndarray]]

OPTIONAL = {"pardiso": ("pypardiso", _Pardiso)}  #: name → (module it needs, backend class)

#: name → backend class; :func:`factorize` makes one instance per :class:`SolverStats` (per solver of a run)
BACKENDS: dict[str, Callable[[], Backend]] = {
    "superlu": _SuperLU,
    **{name: backend for name, (module, backend) in OPTIONAL.items() if importlib.util.find_spec(module)},
}


def factorize(A: sp.spmatrix, stats: SolverStats, backend: str = "superlu") -> Factorized:
    """Factorize ``A`` with ``backend``, counting it on ``stats``.

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
    t0 = time.perf_counter()
    if backend not in stats.backends:
        stats.backends[backend] = BACKENDS[backend]()
    solve = stats.backends[backend](A)
    stats.factorizations += 1
    stats.factorization_s += time.perf_counter() - t0
    return Factorized(solve, stats)
