"""What a :class:`~multilayer.numerics.linsolve.ReusingSolver` holds between two steps, as data.

A checkpoint keeps it (:func:`held`) and a resumed run gives it back (the solver's ``restore``, the matrix
read by :func:`matrix_of`), so the run goes
on as if it had never stopped: the matrix the held factors were made from is factorized again in the
same precision — a deterministic factorization of the same matrix gives the same factors — and the
break-even counters and the GMRES guess span (:class:`~multilayer.numerics.krylov.SolutionSpan`) are
restored as they were.  :func:`check` says whether data read from a file is such a state (a CSR/CSC
matrix whose indices are in range: SuperLU trusts them).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

KEYS = frozenset({"matrix", "double_only", "rate", "excess", "factorization_cost", "span", "count"})
MATRIX = frozenset({"format", "shape", "data", "indices", "indptr", "single"})


def kept(A: sp.spmatrix) -> sp.spmatrix:
    """A CSR or CSC matrix equal to ``A`` whose data no caller refills (its index arrays shared when A has them)."""
    if A.format not in ("csr", "csc"):
        return sp.csc_matrix(A)
    return type(A)((A.data.copy(), A.indices, A.indptr), shape=A.shape)


def held(solver: Any) -> dict[str, Any]:
    """``solver``'s state between two steps: ``matrix``, the one its factors were made from (``format``,
    ``shape``, ``data``, ``indices``, ``indptr``, and ``single``: their precision; None before any),
    ``double_only`` (single-precision factors fell back), the break-even counters ``rate``, ``excess``,
    ``factorization_cost``, the guess ``span`` (its columns in the ring's order) and ``count`` (solutions
    added)."""
    matrix = None
    if solver._factored is not None:
        A, single = solver._factored
        matrix = {"format": A.format, "shape": [int(A.shape[0]), int(A.shape[1])], "data": A.data,
                  "indices": A.indices, "indptr": A.indptr, "single": bool(single)}
    X, count = solver._span.held()
    cost = solver.stats.factorization_cost
    return {"matrix": matrix, "double_only": bool(solver.reuse.factors == "single" and not solver._single),
            "rate": None if solver._rate is None else float(solver._rate), "excess": float(solver._excess),
            "factorization_cost": None if cost is None else float(cost), "span": X, "count": int(count)}


def matrix_of(state: dict[str, Any]) -> tuple[sp.spmatrix, bool] | None:
    """The matrix the held factors of ``state`` (checked by :func:`check`) were made from, and whether they were
    single precision; None when the solver held none.  The solver factorizes it again
    (:meth:`~multilayer.numerics.linsolve.ReusingSolver.restore`)."""
    m = state["matrix"]
    if m is None:
        return None
    kind = sp.csr_matrix if m["format"] == "csr" else sp.csc_matrix
    return kind((m["data"], m["indices"], m["indptr"]), shape=tuple(m["shape"])), m["single"]


def check(state: Any, span: int = 8) -> None:
    """Raise ValueError unless ``state`` is what :func:`held` gives (``span``: the solver's span size): its
    keys and types, the span's shape, a CSR/CSC matrix of float64 data whose indices and indptr are in range."""
    if not isinstance(state, dict) or set(state) != KEYS:
        raise ValueError(f"a solver's held state has the keys {sorted(KEYS)}")
    if not isinstance(state["double_only"], bool) or not isinstance(state["count"], int) or state["count"] < 0:
        raise ValueError("a solver's double_only must be a boolean and count a whole number ≥ 0")
    for name in ("rate", "factorization_cost"):
        if state[name] is not None and not (isinstance(state[name], float) and state[name] > 0.0):
            raise ValueError(f"a solver's {name} must be None or a number > 0")
    if not isinstance(state["excess"], float) or not state["excess"] >= 0.0:
        raise ValueError("a solver's excess must be a number ≥ 0")
    X = state["span"]
    if not (isinstance(X, np.ndarray) and X.dtype == np.float64 and X.ndim == 2
            and X.shape[1] == min(state["count"], span)):
        raise ValueError("a solver's span must be a float64 array of one column per solution held")
    m = state["matrix"]
    if m is None:
        return
    if not isinstance(m, dict) or set(m) != MATRIX:
        raise ValueError(f"a solver's matrix has the keys {sorted(MATRIX)}")
    if m["format"] not in ("csr", "csc") or not isinstance(m["single"], bool):
        raise ValueError("a solver's matrix must be CSR or CSC, its single a boolean")
    shape = m["shape"]
    if not (isinstance(shape, list) and len(shape) == 2
            and all(isinstance(k, int) and not isinstance(k, bool) and k > 0 for k in shape)):
        raise ValueError("a solver's matrix shape must be two whole numbers > 0")
    data, indices, indptr = m["data"], m["indices"], m["indptr"]
    major, minor = shape if m["format"] == "csr" else shape[::-1]
    if not (isinstance(data, np.ndarray) and data.dtype == np.float64 and data.ndim == 1
            and all(isinstance(a, np.ndarray) and a.ndim == 1 and a.dtype.kind == "i" for a in (indices, indptr))
            and indptr.size == major + 1 and indices.size == data.size):
        raise ValueError("a solver's matrix must have float64 data, and integer indices and indptr of its shape")
    if (indptr[0] != 0 or indptr[-1] != data.size or np.any(np.diff(indptr) < 0)
            or (indices.size and (indices.min() < 0 or indices.max() >= minor))):
        raise ValueError("a solver's matrix has indices or an indptr out of range")
    if X.shape[1] and X.shape[0] != shape[0]:
        raise ValueError("a solver's span does not have the matrix's size")
