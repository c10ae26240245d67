"""GMRES preconditioned by the LU factors of a nearby matrix, on the true residual.

Between two steps the fluid's Oseen matrix changes by O(Δt) (the advecting
velocity, the ALE coefficients of the moved domain), so the factors L U of
an earlier step's matrix A₀ make A U⁻¹L⁻¹ = I + (A − A₀)A₀⁻¹ a small
perturbation of the identity: GMRES on it converges in a few iterations.
The preconditioning is on the right — GMRES minimizes the true residual
‖b − A x‖₂, not a preconditioned one — and the result is checked with one
more product, so the tolerance is a statement about A x = b itself.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def preconditioned_gmres(A: sp.spmatrix, b: np.ndarray, precondition: Callable[[np.ndarray], np.ndarray],
                         tolerance: float, max_iterations: int,
                         guess: np.ndarray | None = None) -> tuple[np.ndarray | None, int]:
    """Solve A x = b by GMRES on A M⁻¹ (M⁻¹ = ``precondition``), starting from x₀ = g + M⁻¹(b − A g).

    g is the ``guess`` (0 by default): GMRES solves for the correction, so a
    guess whose residual is already small — the solution extrapolated from
    earlier steps — leaves fewer orders of magnitude to gain.

    Parameters
    ----------
    A : sparse matrix
        The matrix of the system.
    b : ndarray
        Right-hand side.
    precondition : callable
        b ↦ M⁻¹ b, the solve with the factors of a nearby matrix.
    tolerance : float
        Relative residual ‖b − A x‖₂ / ‖b‖₂ to reach.
    max_iterations : int
        GMRES iterations allowed (one cycle, no restart).
    guess : ndarray, optional
        g, an approximation of x.

    Returns
    -------
    x : ndarray or None
        The solution, or None when the tolerance was not reached.
    iterations : int
            GMRES iterations done (0 when x₀ is already good enough).

    Examples
    --------
    >>> A = sp.diags([2.0, 3.0, 4.0]).tocsr()
    >>> x, its = preconditioned_gmres(A, np.ones(3), lambda r: r / 3.0, 1e-12, 5)
    >>> bool(np.allclose(x, [0.5, 1 / 3, 0.25])), its <= 3
    (True, True)
    """
    norm_b = float(np.linalg.norm(b))
    if norm_b == 0.0:
        return np.zeros_like(b), 0
    target = tolerance * norm_b
    count = [0]

    def counted(_residual) -> None:
        count[0] += 1

    # the guess is corrected once by the preconditioner even when its residual is already small: with
    # the factors of A itself that makes x₀ exact to round-off, as a direct solve is
    r = b if guess is None else b - A @ guess
    operator = spla.LinearOperator(A.shape, matvec=lambda y: A @ precondition(y), dtype=float)
    # GMRES for y with A M⁻¹ y = r = b − A g, started at y₀ = r; x = g + M⁻¹ y
    y, _ = spla.gmres(operator, r, x0=r.copy(), rtol=0.0, atol=0.5 * target, restart=max_iterations,
                      maxiter=1, callback=counted, callback_type="pr_norm")
    x = precondition(y) if guess is None else guess + precondition(y)
    if np.linalg.norm(b - A @ x) > target:
        return None, count[0]
    return x, count[0]
