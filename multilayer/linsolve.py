"""Sparse direct solvers behind one small interface, with factorization counting.

A :class:`Factorized` is what a step needs: ``solve(b)``.  Backends are looked
up by name; ``"superlu"`` (scipy) is always there.  Every factorization is
counted and timed on the :class:`SolverStats` passed in, so a run can prove
that a matrix which never changes was factorized once.
"""

from __future__ import annotations

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


def _superlu(A: sp.spmatrix) -> Callable[[np.ndarray], np.ndarray]:
    lu = spla.splu(sp.csc_matrix(A), permc_spec="COLAMD")
    return lu.solve


BACKENDS: dict[str, Callable[[sp.spmatrix], Callable[[np.ndarray], np.ndarray]]] = {
    "superlu": _superlu,
}


def factorize(A: sp.spmatrix, stats: SolverStats, backend: str = "superlu") -> Factorized:
    """Factorize ``A`` with ``backend``, counting it on ``stats``.

    >>> st = SolverStats()
    >>> f = factorize(sp.eye(3).tocsc() * 2.0, st)
    >>> f.solve(np.ones(3)), st.factorizations
    (array([0.5, 0.5, 0.5]), 1)
    """
    if backend not in BACKENDS:
        raise KeyError(f"unknown linear solver {backend!r}; available: {sorted(BACKENDS)}")
    t0 = time.perf_counter()
    solve = BACKENDS[backend](A)
    stats.factorizations += 1
    stats.factorization_s += time.perf_counter() - t0
    return Factorized(solve, stats)
