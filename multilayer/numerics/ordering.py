"""Fill-reducing orderings of a sparsity pattern, computed once and reused.

A step's matrices keep their sparsity pattern for a whole run (the fluid's
:class:`~multilayer.numerics.assembly.pattern.Pattern`, the monolithic layout), so
the ordering that decides the fill of an LU factorization is a property of
the pattern, not of the values: it is computed on the first factorization
and reused by every later one (the split PARDISO makes into symbolic and
numeric phases).

:func:`nested_dissection` is METIS's nested dissection (through pymetis) of
the symmetrized graph of A + Aᵀ.  On the 2D saddle-point systems here it
fills much less than SuperLU's default column ordering (COLAMD): at 277k
fluid unknowns, 211 entries per row of L + U against 663, a factorization
6× faster (docs/performance.md, "The ordering").
"""

from __future__ import annotations

import hashlib

import numpy as np
import scipy.sparse as sp


def pattern_key(A: sp.spmatrix) -> tuple:
    """A key of A's sparsity pattern: format, shape and the digests of its index arrays.

    A CSR or CSC matrix is keyed in its own format (its indices sorted in
    place), anything else as CSC, so a caller holding either pays no conversion.

    >>> A = sp.csc_matrix(np.eye(3)); B = 2.0 * A
    >>> pattern_key(A) == pattern_key(B), pattern_key(A) == pattern_key(sp.csc_matrix(np.ones((3, 3))))
    (True, False)
    """
    if A.format not in ("csr", "csc"):
        A = sp.csc_matrix(A)
    A.sort_indices()
    return (A.format, A.shape, hashlib.sha1(np.ascontiguousarray(A.indptr, dtype=np.int64)).digest(),
            hashlib.sha1(np.ascontiguousarray(A.indices, dtype=np.int64)).digest())


def nested_dissection(A: sp.spmatrix) -> np.ndarray:
    """The permutation p (new position k holds old index p[k]) of METIS nested dissection of A + Aᵀ.

    The graph is that of A's stored entries whatever their values, so every
    matrix of one pattern gets the same ordering.  A matrix without
    off-diagonal entries keeps its order.

    >>> A = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(7, 7))
    >>> p = nested_dissection(A)
    >>> sorted(p.tolist()) == list(range(7))
    True
    """
    import pymetis

    n = A.shape[0]
    if A.shape != (n, n):
        raise ValueError(f"an ordering needs a square matrix, not {A.shape}")
    # the graph of the stored entries, explicit zeros included: the ordering belongs to the pattern, not
    # to the values (a matrix at rest has zeros where later ones have not, and one pattern gets one ordering)
    C = sp.csr_matrix(A)
    G = sp.csr_matrix((np.ones(C.nnz), C.indices, C.indptr), shape=C.shape)
    S = (G + G.T).tocsr()
    S.setdiag(0.0)
    S.eliminate_zeros()
    if S.nnz == 0:
        return np.arange(n)
    xadj, adjncy = S.indptr.astype(np.int32), S.indices.astype(np.int32)
    if hasattr(pymetis, "CSRAdjacency"):  # pymetis ≥ 2025.1; the keyword form is deprecated there
        perm, _ = pymetis.nested_dissection(pymetis.CSRAdjacency(xadj, adjncy))
    else:
        perm, _ = pymetis.nested_dissection(xadj=xadj, adjncy=adjncy)
    perm = np.asarray(perm, dtype=np.int64)
    if not np.array_equal(np.sort(perm), np.arange(n)):  # a defensive check on what the library returned
        raise RuntimeError("METIS returned an ordering that is not a permutation")
    return perm
