"""Newton's method: the one loop every wall solve goes through (a wall step, a monolithic step, the static start).

A solve is R(x) = 0, R the out-of-balance force (loads minus the forces of
the state x), by corrections x ← x + J(x)⁻¹ R(x) with J = −∂R/∂x the
tangent.  The caller gives the residual and the solve with its tangent;
:func:`newton` runs the loop and says how it converged.

A linear problem (R affine, J its constant matrix, solved exactly) is
solved by its first correction: from a start at zero it IS the linear
solve J⁻¹R(0), so the loop does that solve and nothing else — no residual
is evaluated, no counter is touched.

A nonlinear one iterates until the residual, relative to the size of the
terms it balances (a vector the caller adds up from their magnitudes, so
that round-off in them sets the floor), is at most :data:`TOLERANCE`.  Its
corrections are solved by the caller's solver: in this project a
:class:`~multilayer.numerics.linsolve.ReusingSolver`, which solves each
tangent to its tolerance by GMRES on a held factorization and refactorizes
when that stalls — so the loop is Newton's, quadratic near the solution,
while the factorizations are reused (theory §4, "Nonlinear layers").

x + x³ = 2 from x = ½: the full first correction (to x = 1.29) would raise |R| from 1.38 to 1.41, so it is
halved (:func:`_line_search`); then the relative residual is squared at each correction:

>>> import numpy as np
>>> cubic = lambda x: (np.array([2.0]) - x - x**3, np.array([2.0]) + np.abs(x) + np.abs(x**3))
>>> result = newton(cubic, lambda x, r: r / (1.0 + 3.0 * x**2), np.array([0.5]))
>>> result.x, result.iterations, [f"{h:.0e}" for h in result.residuals]
(array([1.]), 5, ['5e-01', '1e-01', '9e-03', '7e-05', '3e-09', '0e+00'])
"""

from __future__ import annotations

from collections.abc import Callable

import attrs
import numpy as np

#: the relative residual ‖R‖/‖size of its terms‖ a nonlinear solve ends at: a step's energy identity then closes
#: to about that (the runner's ledger asks 1e-9)
TOLERANCE = 1e-11
#: corrections allowed before the solve is given up
MAX_ITERATIONS = 25
#: halvings of a correction that does not lower the residual (:func:`_line_search`), and the share of λ‖R‖ a
#: cut-back step must take off ‖R‖ (Armijo's condition on ‖R‖)
HALVINGS = 10
SUFFICIENT = 1e-4

#: the coupled steps' ``chord`` (:func:`newton`; the monolithic step, the kinematic splitting's wall step): their
#: tangent held while each correction lowers the relative residual by 0.03 at least.  On the carotid-like tube of
#: benchmarks/hyperelastic_step.py a monolithic Crank–Nicolson step then takes four or five corrections on two
#: tangents, each factorized once, instead of three on three (docs/performance.md, "Hyperelastic layers"); at 0.1
#: the kinematic splitting's hardest steps crawled, the residual falling 0.08 a correction
CHORD = 0.03

Residual = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
Solve = Callable[[np.ndarray | None, np.ndarray], np.ndarray]


class NewtonError(RuntimeError):
    """A Newton solve that did not converge; the message has its residuals."""


@attrs.frozen(eq=False)
class NewtonResult:
    """The solution, the corrections it took, and the relative residual at the start and after each one
    (empty for a linear problem: its one correction is exact, no residual is evaluated)."""

    x: np.ndarray
    iterations: int
    residuals: tuple[float, ...] = ()


def relative(r: np.ndarray, size: np.ndarray) -> float:
    """‖r‖ / ‖size‖ (0 when both are 0)."""
    scale = float(np.linalg.norm(size))
    norm = float(np.linalg.norm(r))
    return norm / scale if scale > 0.0 else norm


def at_trial(residual: Residual, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """R(x), its size and the relative residual at a trial state ``x`` (a Newton correction, one cut back, a
    solve's start), numpy's floating-point warnings silenced: a state outside a layer's range — a fibre stretch
    whose exp(k₂E²) overflows, an element turned inside out (J ≤ 0) — gives a residual that is not finite (nan
    relative residual), and the caller rejects it (a shorter step, or a solve refused with its residuals); a
    warning would say nothing more."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        r, size = residual(x)
        finite = bool(np.all(np.isfinite(r)) and np.all(np.isfinite(size)))
        return r, size, relative(r, size) if finite else np.nan


def _line_search(residual: Residual, x: np.ndarray, delta: np.ndarray, r: np.ndarray,
                 current: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """x + λΔ, its residual, size and relative residual h: λ = 1 where that lowers h or ‖R‖, else halved until
    ‖R‖ falls by at least ``SUFFICIENT`` λ of itself (at most ``HALVINGS`` times; the last finite trial if none
    does).

    Δ = J⁻¹R is a direction in which ‖R‖ falls (its derivative along Δ is −‖R‖ for the exact J), so a short
    enough step lowers it: a correction that overshoots — a large step of a stiffening wall, fibres passing
    from taut to slack, a trial state past J = 0 where the residual is nan — is cut back instead of throwing
    the iteration out of the basin where it converges quadratically.  Near the solution the full step
    lowers both quadratically, and it is the one taken.
    """
    norm = float(np.linalg.norm(r))
    step, last = 1.0, None
    for _ in range(HALVINGS + 1):
        trial = x + step * delta
        r_trial, size, h = at_trial(residual, trial)
        if np.isfinite(h):
            last = (trial, r_trial, size, h)
            norm_trial = float(np.linalg.norm(r_trial))
            if norm_trial <= (1.0 - SUFFICIENT * step) * norm:
                return last
        step *= 0.5
    return (trial, r_trial, size, h) if last is None else last  # (not finite: the loop reports it)


def newton(residual: Residual | None, solve: Solve, start: np.ndarray | None, linear: bool = False,
           first: np.ndarray | None = None, stats=None, tolerance: float = TOLERANCE,
           max_iterations: int = MAX_ITERATIONS, what: str = "the wall", chord: float | None = None) -> NewtonResult:
    """x with R(x) = 0 by Newton's corrections x ← x + λJ(x)⁻¹R(x), λ = 1 unless that raises the residual (:func:`_line_search`).

    Parameters
    ----------
    residual : callable
        x ↦ (R(x), size): the out-of-balance force and, entry by entry, the sum of the magnitudes of the
        terms it is made of.
    solve : callable
        (x, r) ↦ J(x)⁻¹ r, with x None for the start at zero.
    start : array or None
        x₀; for a linear problem None stands for zero, and the first correction is then the solution itself.
    linear : bool
        R is affine and ``solve`` exact: the first correction solves it.  ``first`` is then R(x₀), as the
        caller computes the right-hand side of its linear system.
    stats : SolverStats, optional
        Where a nonlinear solve's corrections and final residual are counted (``newton_*``).
    what : str
        What is solved, for the message of a solve that does not converge.
    chord : float, optional
        Hold the tangent (modified Newton): ``solve`` is given the iterate where it was last taken, first the
        start, while each correction lowers the relative residual by this factor at least; after one that does
        not, it is taken at the new iterate.  The iteration then converges linearly, each correction at the
        rate the tangent's change allows, and its solves reuse the held tangent's factorization.

    Raises
    ------
    NewtonError
        When the residual is not finite, or still above ``tolerance`` after ``max_iterations`` corrections.

    Examples
    --------
    The module's x + x³ = 2 from x = 1.1 with ``chord``: the tangent of the start serves while the residual
    falls tenfold a correction; 9e-4 after 7e-3 does not, and the tangent is taken again there, at x = 1.0009:

    >>> cubic = lambda x: (np.array([2.0]) - x - x**3, np.array([2.0]) + np.abs(x) + np.abs(x**3))
    >>> at = []
    >>> def solve(x, r):
    ...     at.append(round(float(x[0]), 4))
    ...     return r / (1.0 + 3.0 * x**2)
    >>> result = newton(cubic, solve, np.array([1.1]), chord=0.1)
    >>> result.x, [f"{h:.0e}" for h in result.residuals], at
    (array([1.]), ['1e-01', '7e-03', '9e-04', '6e-07', '8e-10', '1e-12'], [1.1, 1.1, 1.0009, 1.0009, 1.0009])
    """
    if linear:
        r = first if first is not None else residual(start)[0]
        delta = solve(start, r)
        return NewtonResult(delta if start is None else start + delta, 1)
    x = start
    r, size, h = at_trial(residual, x)
    history = [h]
    anchor = None if chord is None else x  # where the held tangent was taken (None: at every iterate)
    iterations = 0
    while not history[-1] <= tolerance:  # (a nan residual is not converged: it fails below)
        if iterations == max_iterations or not np.isfinite(history[-1]):
            seen = ", ".join(f"{h:.2e}" for h in history)
            raise NewtonError(f"{what}: Newton's iteration did not converge in {iterations} corrections (relative "
                              f"residuals {seen}; tolerance {tolerance:g}): a smaller Δt, or a layer whose tangent "
                              "is not the derivative of its force (multilayer check-plugin checks it)")
        x, r, size, h = _line_search(residual, x, solve(x if anchor is None else anchor, r), r, history[-1])
        iterations += 1
        history.append(h)
        if anchor is not None and not h <= chord * history[-2]:  # the held tangent serves no more: take it here
            anchor = x
    if stats is not None:
        stats.newton_solves += 1
        stats.newton_iterations += iterations
        stats.newton_max_iterations = max(stats.newton_max_iterations, iterations)
        stats.newton_residual = max(stats.newton_residual, history[-1])
        stats.newton_last_residual = history[-1]
    return NewtonResult(x, iterations, tuple(history))


__all__ = ["CHORD", "MAX_ITERATIONS", "TOLERANCE", "NewtonError", "NewtonResult", "at_trial", "newton", "relative"]
