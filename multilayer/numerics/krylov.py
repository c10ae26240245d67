"""GMRES preconditioned by the LU factors of a nearby matrix, on the true residual.

Between two steps the fluid's Oseen matrix changes by O(Δt) (the advecting
velocity, the ALE coefficients of the moved domain), so the factors L U of
an earlier step's matrix A₀ make A U⁻¹L⁻¹ = I + (A − A₀)A₀⁻¹ a small
perturbation of the identity: GMRES on it converges in a few iterations.
The preconditioning is on the right — GMRES minimizes the true residual
‖b − A x‖₂, not a preconditioned one — and the result is checked with one
more product, so the tolerance is a statement about A x = b itself.

The GMRES here is written out (Arnoldi with classical Gram–Schmidt done
twice, Givens rotations) rather than taken from scipy, for one reason: it
keeps the preconditioned directions z_j = M⁻¹ v_j, so x = x₀ + Σ y_j z_j
costs no back-substitution beyond one per iteration.  scipy's ``gmres``
pays two more per solve (the residual of its start and the final M⁻¹),
and a back-substitution costs 10–20 matrix–vector products here.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp


class SolutionSpan:
    """The solutions of the latest ``size`` systems of a sequence, and the start they give the next one.

    The guess is the x in their span with the least residual,

        x₀ = X c,   c = argmin ‖b − A X c‖₂,   X = [x^{n−k+1} … xⁿ],

    (Fischer's projection of successive right-hand sides, CMAME 163, 1998,
    with a changing matrix: the residual minimized rather than the A-norm of
    the error).  The span holds every polynomial extrapolation of degree
    < k, so the guess is never worse than the best of them (in exact
    arithmetic) and is exact when the solutions are such a polynomial of the
    step; where the solution's history has a kink (a load that starts or stops) it
    weighs the solutions by what fits the new system, not by a fixed rule.
    It costs k products with A and a k-column least-squares solve.  On the
    quick-start case at 22k unknowns (steps 17–120, ``benchmarks/guess.py``)
    k = 8 leaves a median residual of 8.4e-9 against the quadratic
    extrapolation's 1.3e-4, and 3.4e-4 against 4.9e-3 at the worst step
    (docs/performance.md, "The guess").  Where a system's solutions carry a
    part that changes irregularly from step to step, no combination predicts
    it and the span gains little (the monolithic Crank–Nicolson system:
    1.3e-3 against 2.9e-3).

    The columns are kept in a ring (their order does not change the span);
    a solution of another length starts it afresh.
    """

    def __init__(self, size: int) -> None:
        if size < 1:
            raise ValueError(f"a span of {size!r} solutions: expected at least 1")
        self.size = size
        self._X: np.ndarray | None = None  # (n, size), column j % size holds the j-th solution added
        self._count = 0

    def __len__(self) -> int:
        return min(self._count, self.size)

    def clear(self) -> None:
        self._count = 0

    def held(self) -> tuple[np.ndarray, int]:
        """(X, count): the solutions held, as the columns of the ring (their order kept), and how many were added.

        What :meth:`restore` needs to give the same guesses, bit for bit (a checkpoint keeps it).
        """
        m = len(self)
        X = np.empty((0, 0)) if self._X is None else self._X[:, :m].copy()
        return X, self._count

    def restore(self, X: np.ndarray, count: int) -> None:
        """Hold again what :meth:`held` gave: the ring's columns ``X`` after ``count`` solutions added."""
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[1] != min(count, self.size) or count < 0:
            raise ValueError(f"a span of {self.size} solutions cannot hold {X.shape} after {count} added")
        if count == 0:
            self._X, self._count = None, 0
            return
        self._X = np.empty((X.shape[0], self.size))
        self._X[:, : X.shape[1]] = X
        self._count = count

    def add(self, x: np.ndarray) -> None:
        if self._X is None or self._X.shape[0] != x.shape[0]:
            self._X, self._count = np.empty((x.shape[0], self.size)), 0
        self._X[:, self._count % self.size] = x
        self._count += 1

    def guess(self, A: sp.spmatrix, b: np.ndarray) -> np.ndarray | None:
        """The least-residual x in the span (None when it holds no solution of b's length)."""
        start = self.start(A, b)
        return None if start is None else start[0]

    def start(self, A: sp.spmatrix, b: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """(x₀, r₀): the least-residual x in the span and its residual b − A x₀ (None as :meth:`guess`).

        r₀ = b − (A X) c comes from the product the least-squares problem
        already formed, so GMRES started here does not pay one more product
        with A for it; it equals b − A (X c) to round-off, and the residual
        GMRES stops on is checked afresh anyway.
        """
        m = len(self)
        if m == 0 or self._X.shape[0] != b.shape[0]:
            return None
        X = self._X if m == self.size else self._X[:, :m]
        AX = A @ X
        c = np.linalg.lstsq(AX, b, rcond=None)[0]  # SVD: repeated solutions (a steady flow) lose rank, not accuracy
        if not np.all(np.isfinite(c)):
            return None
        return X @ c, b - AX @ c


class Workspace:
    """The Arnoldi basis V and the directions Z of one system size, kept between solves.

    A large system solved every step would otherwise take fresh pages for
    2 (m + 1) vectors each time.
    """

    def __init__(self) -> None:
        self._arrays: tuple[np.ndarray, np.ndarray] | None = None

    def arrays(self, m: int, n: int) -> tuple[np.ndarray, np.ndarray]:
        if self._arrays is None or self._arrays[0].shape != (m + 1, n):
            self._arrays = (np.empty((m + 1, n)), np.empty((m, n)))
        return self._arrays


class GMRESResult(NamedTuple):
    """What :func:`preconditioned_gmres` returns."""

    x: np.ndarray | None  #: the solution, or None when the tolerance was not reached
    iterations: int  #: GMRES iterations done (= back-substitutions)
    start: float  #: ‖b − A x₀‖₂, the residual GMRES started from
    end: float  #: ‖b − A x‖₂ of the returned x, checked afresh (nan when there is none)


def preconditioned_gmres(A: sp.spmatrix, b: np.ndarray, precondition: Callable[[np.ndarray], np.ndarray],
                         tolerance: float, max_iterations: int, guess: np.ndarray | None = None,
                         workspace: Workspace | None = None,
                         residual: np.ndarray | None = None) -> GMRESResult:
    """Solve A x = b by GMRES on A M⁻¹ (M⁻¹ = ``precondition``) from x₀ = ``guess`` (0 by default).

    One cycle of at most ``max_iterations`` iterations, each one
    back-substitution z_j = M⁻¹ v_j and one product A z_j; at least one is
    done even when the guess already meets the tolerance, so with the factors
    of A itself the answer is the direct solve's, exact to round-off.  When
    the least-squares residual |g_{j+1}| meets the target, the true residual
    ‖b − A x‖₂ ≤ ``tolerance`` · ‖b‖₂ is checked; where round-off leaves it
    above, the iteration goes on.

    Parameters
    ----------
    A : sparse matrix
        The matrix of the system.
    b : ndarray
        Right-hand side.
    precondition : callable
        v ↦ M⁻¹ v, the solve with the factors of a nearby matrix.
    tolerance : float
        Relative residual ‖b − A x‖₂ / ‖b‖₂ to reach.
    max_iterations : int
        GMRES iterations allowed (one cycle, no restart).
    guess : ndarray, optional
        x₀, an approximation of x: GMRES solves for the correction, so a
        guess whose residual is already small leaves fewer orders of
        magnitude to gain.
    workspace : Workspace, optional
        Where the basis vectors live (fresh arrays when not given).
    residual : ndarray, optional
        b − A ``guess`` when the caller has it (:meth:`SolutionSpan.start`):
        one product with A fewer.  Ignored without a guess.

    Returns
    -------
    GMRESResult
        (x, iterations, start, end): the solution (None when the tolerance
        was not reached), the iterations done (= back-substitutions), and
        the norms of the residuals it started from and ended at — their
        ratio per iteration is how well the preconditioner fits A.

    Examples
    --------
    >>> A = sp.diags([2.0, 3.0, 4.0]).tocsr()
    >>> x, its, start, end = preconditioned_gmres(A, np.ones(3), lambda r: r / 3.0, 1e-12, 5)
    >>> bool(np.allclose(x, [0.5, 1 / 3, 0.25])), its, bool(end <= 1e-12 * start)
    (True, 3, True)
    """
    norm_b = float(np.linalg.norm(b))
    if norm_b == 0.0:
        return GMRESResult(np.zeros_like(b), 0, 0.0, 0.0)
    target = tolerance * norm_b
    m, n = max_iterations, b.shape[0]
    V, Z = (workspace or Workspace()).arrays(m, n)
    x0 = np.zeros_like(b) if guess is None else guess
    r = b if guess is None else (b - A @ guess if residual is None else residual)
    beta = float(np.linalg.norm(r))
    H = np.zeros((m + 1, m))
    cs, sn = np.zeros(m), np.zeros(m)
    g = np.zeros(m + 1)
    g[0] = beta
    if beta == 0.0:
        return GMRESResult(x0.copy(), 0, 0.0, 0.0)
    np.divide(r, beta, out=V[0])
    for j in range(m):
        Z[j] = precondition(V[j])
        w = A @ Z[j]
        basis = V[: j + 1]
        h = basis @ w
        w -= basis.T @ h
        again = basis @ w  # the second pass makes classical Gram–Schmidt as orthogonal as modified
        w -= basis.T @ again
        h += again
        H[: j + 1, j] = h
        H[j + 1, j] = np.linalg.norm(w)
        if not np.isfinite(H[j + 1, j]):  # a preconditioner that returned inf or nan: no answer from it
            return GMRESResult(None, j + 1, beta, np.nan)
        if H[j + 1, j] > 0.0:
            np.divide(w, H[j + 1, j], out=V[j + 1])
        for i in range(j):  # the earlier rotations, on the new column
            H[i, j], H[i + 1, j] = cs[i] * H[i, j] + sn[i] * H[i + 1, j], -sn[i] * H[i, j] + cs[i] * H[i + 1, j]
        d = np.hypot(H[j, j], H[j + 1, j])
        cs[j], sn[j] = H[j, j] / d, H[j + 1, j] / d
        H[j, j], H[j + 1, j] = d, 0.0
        g[j], g[j + 1] = cs[j] * g[j], -sn[j] * g[j]
        if abs(g[j + 1]) <= target or j + 1 == m:
            y = sla.solve_triangular(H[: j + 1, : j + 1], g[: j + 1])
            x = x0 + Z[: j + 1].T @ y
            end = float(np.linalg.norm(b - A @ x))
            if end <= target:
                return GMRESResult(x, j + 1, beta, end)
            # the true residual is above the least-squares one by round-off: one more iteration, if allowed
    return GMRESResult(None, m, beta, np.nan)
