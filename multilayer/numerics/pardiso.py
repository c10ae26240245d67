"""MKL PARDISO as a backend of :func:`multilayer.numerics.linsolve.factorize` (``"pardiso"``, the optional extra
``fast``): its symbolic analysis kept per sparsity pattern, only the numeric factorization redone."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from multilayer.numerics.ordering import pattern_key


def _pypardiso():
    try:
        import pypardiso
    except ImportError as exc:  # registered, but it (or MKL's runtime) did not load
        raise RuntimeError(f"linear solver 'pardiso' needs pypardiso: pip install 'multilayer[fast]' ({exc})") from exc
    return pypardiso


class Pardiso:
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
        key = pattern_key(A)  # sorts A's indices, as PARDISO needs
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
