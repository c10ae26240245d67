"""A sparsity pattern fixed at setup, filled with new values every step.

The A2 matrix changes every step but its nonzero structure does not.  The
pattern is built once from the (row, column) lists of every term; after
that a step only computes values and sums them into the CSR data array
(:class:`Filler`, ``np.add.at`` of each term into a kept array) — no sorting, no duplicate summation,
no new index arrays.  Sub-matrices (the free/fixed blocks of a Dirichlet elimination)
are index maps into the same data array.  A fixed pattern is also what
lets a solver backend keep its symbolic analysis (PARDISO) or its
fill-reducing ordering (SuperLU, :mod:`multilayer.numerics.ordering`) from one
factorization to the next.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


class Pattern:
    """The CSR structure of the union of several COO (row, column) lists.

    >>> p = Pattern((2, 2), [(np.array([0, 1, 0]), np.array([0, 1, 0]))])
    >>> fill = p.filler([p.slots(np.array([0, 1, 0]), np.array([0, 1, 0]))])
    >>> p.matrix(fill(np.array([1.0, 2.0, 3.0]))).toarray().tolist()
    [[4.0, 0.0], [0.0, 2.0]]
    """

    def __init__(self, shape: tuple[int, int], entries: list[tuple[np.ndarray, np.ndarray]]):
        self.shape = shape
        keys = np.concatenate([self._key(r, c) for r, c in entries])
        keys.sort()  # sort-based unique: numpy's hash-based np.unique took 10 s on 13M keys (297k unknowns)
        keys = keys[np.concatenate(([True], keys[1:] != keys[:-1]))] if keys.size else keys
        self._keys = keys
        rows = keys // shape[1]
        self.indices = (keys % shape[1]).astype(np.int32)
        self.indptr = np.searchsorted(rows, np.arange(shape[0] + 1)).astype(np.int32)

    def _key(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        return np.asarray(rows, dtype=np.int64) * self.shape[1] + np.asarray(cols, dtype=np.int64)

    @property
    def nnz(self) -> int:
        return len(self._keys)

    def slots(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Positions of the entries (rows, cols) in the data array; all must be in the pattern."""
        keys = self._key(rows, cols)
        pos = np.searchsorted(self._keys, keys)
        pos = np.clip(pos, 0, self.nnz - 1)
        if not np.array_equal(self._keys[pos], keys):
            raise ValueError("entries outside the fixed sparsity pattern")
        return pos

    def filler(self, slots: list[np.ndarray], scales: list[float] | None = None) -> Filler:
        """A :class:`Filler` of this pattern for terms at ``slots`` times ``scales`` (concatenated once)."""
        return Filler(self.nnz, slots, scales)

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        """The CSR matrix of this pattern with ``data`` (arrays shared, not copied)."""
        return sp.csr_matrix((data, self.indices, self.indptr), shape=self.shape, copy=False)

    def block(self, rows: np.ndarray, cols: np.ndarray) -> Block:
        """The sub-matrix [rows][:, cols] as a :class:`Block` of this pattern."""
        tag = self.matrix(np.arange(1, self.nnz + 1, dtype=np.float64))
        sub = tag[rows][:, cols].tocsr()
        sub.sort_indices()
        return Block(sub.indices, sub.indptr, sub.data.astype(np.int64) - 1, sub.shape)


class Block:
    """A sub-matrix of a :class:`Pattern`: its own CSR structure and where its data sits in the parent's.

    >>> p = Pattern((2, 2), [(np.array([0, 0, 1]), np.array([0, 1, 1]))])
    >>> b = p.block(np.array([0]), np.array([1]))
    >>> b.matrix(np.array([1.0, 2.0, 3.0])).toarray().tolist()
    [[2.0]]
    """

    def __init__(self, indices: np.ndarray, indptr: np.ndarray, take: np.ndarray, shape: tuple[int, int]):
        self.indices, self.indptr, self.take, self.shape = indices, indptr, take, shape
        self._values: np.ndarray | None = None  # the kept values of ``matrix(..., keep=True)``

    def matrix(self, data: np.ndarray, keep: bool = False) -> sp.csr_matrix:
        """The block of the parent matrix whose CSR data is ``data``.

        With ``keep`` the block's values are gathered into an array the block
        keeps, which the matrix shares and the next ``keep`` call overwrites: a
        caller that takes the block every step pays no fresh array (and its
        page faults) each time.
        """
        if not keep:
            return sp.csr_matrix((data[self.take], self.indices, self.indptr), shape=self.shape)
        if self._values is None:
            self._values = np.empty(len(self.take))
        # mode='clip' (the slots are valid by construction): with the default 'raise' numpy buffers ``out``, a
        # fresh array as large as the block every step
        np.take(data, self.take, out=self._values, mode="clip")
        return sp.csr_matrix((self._values, self.indices, self.indptr), shape=self.shape)


class Filler:
    """Sums the values of a step's terms into a pattern's data array, at slots concatenated once.

    Unbuffered ``np.add.at`` (``np.subtract.at`` for a scale of −1) of each
    term's values into a data array kept for the run: the sums are
    ``bincount``'s over the concatenated slots, in the same order; no sorting,
    no duplicate summation, no index arrays built per step, and no fresh
    array — on a large mesh a new data array each step costs its page
    faults.  Values scaled by ±1 are summed as they are (no scaled copy).
    The returned array is the filler's own and is overwritten by its next call.

    >>> p = Pattern((2, 2), [(np.array([0, 1]), np.array([0, 1]))])
    >>> fill = p.filler([p.slots(np.array([0, 1]), np.array([0, 1])), p.slots(np.array([0]), np.array([0]))],
    ...                 scales=[1.0, -1.0])
    >>> fill(np.array([1.0, 2.0]), np.array([3.0])).tolist()
    [-2.0, 2.0]
    """

    def __init__(self, nnz: int, slots: list[np.ndarray], scales: list[float] | None = None):
        self.nnz = nnz
        self.sizes = [len(s) for s in slots]
        self.scales = [1.0] * len(slots) if scales is None else [float(c) for c in scales]
        self.slots = np.concatenate(slots)
        self._cuts = np.cumsum([0, *self.sizes])
        self._scaled = np.empty(max([n for n, c in zip(self.sizes, self.scales) if abs(c) != 1.0], default=0))
        self._data = np.empty(nnz)

    def __call__(self, *values: np.ndarray) -> np.ndarray:
        if [np.size(v) for v in values] != self.sizes:
            raise ValueError(f"values of sizes {[np.size(v) for v in values]}, the slots are {self.sizes}")
        self._data.fill(0.0)
        for v, c, a, b in zip(values, self.scales, self._cuts[:-1], self._cuts[1:]):
            v, slots = np.ravel(v), self.slots[a:b]
            if c == 1.0:
                np.add.at(self._data, slots, v)
            elif c == -1.0:  # data − v is data + (−v) to the bit
                np.subtract.at(self._data, slots, v)
            else:
                np.add.at(self._data, slots, np.multiply(v, c, out=self._scaled[: b - a]))
        return self._data
