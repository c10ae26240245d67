"""A prestressed start: the wall's stress-free reference found from its geometry as imaged under a pressure.

With ``[initial] prestress = true`` the case's geometry is the wall as imaged
at ``initial.pressure`` = P⁰ (an artery on a scan at its diastolic pressure),
not the wall unloaded.  The layers that take a stress-free reference off
their mesh (finite-strain layers: :meth:`~multilayer.wall.layer.Layer.takes_reference`)
are given the one under which the wall under P⁰ sits on the mesh: the
displacement D of that reference from the mesh is found by the backward
displacement fixed point (Bols et al. 2013)

    D⁰ = 0,     dᵏ = the equilibrium under P⁰ on the reference Dᵏ, from the mesh,     Dᵏ⁺¹ = Dᵏ − β dᵏ,

β = ½ with Anderson's acceleration over the last iterates (the plain iteration's
error is multiplied by 1 − λ at a hoop stretch λ, and diverges beyond λ = 2),
dᵏ solved as the static start solves (:func:`~multilayer.wall.equilibrium.static_deflection`:
Newton's method, load steps where one solve does not reach it).  Once the
correction is below :data:`SWITCH` of |D| (or stalls), Newton's method on the
reference itself takes over: R(D) = f(P⁰) − f_int(0; D) = 0, its Jacobian
applied by differences of the forces and solved by GMRES preconditioned by
−K_T(0; D).  Its solution, d = 0, is the wall under P⁰ on the mesh: the
iteration stops when the out-of-balance force of the mesh's state on the
reference is within the static solves' tolerance of the size of its terms,
or the correction within :data:`PRECISION` of |D|, so that a run started
there, with the fluid at rest at P⁰, starts in equilibrium (its first solves
move the wall by round-off).  A soft wall imaged far from its reference is
reached in steps of the pressure (:data:`FIRST_STEP`).  Each layer's energy
on its reference is a function W(d) of the displacement from the mesh
(:meth:`~multilayer.wall.layer.Layer.forms_on_reference`), so its force and
tangent are W's gradient and Hessian and the energy ledger is unchanged;
the layers that take no reference (linear ones) are unloaded at the mesh
and carry none of P⁰.

The iteration is refused (:class:`PrestressError`, at ``initial.prestress``) when it does not converge: a
forward solve fails, Newton's correction does not lower the out-of-balance force, or :data:`MAX_ITERATIONS`
pass, in every step of the pressure down to :data:`SMALLEST_STEP`.
"""

from __future__ import annotations

import attrs
import numpy as np
from scipy.sparse.linalg import LinearOperator, gmres

from multilayer.numerics.linsolve import SolverStats, factorize
from multilayer.numerics.newton import TOLERANCE, NewtonError, at_trial, relative
from multilayer.wall.checks import LayerError
from multilayer.wall.equilibrium import (
    Unsettled,
    loads,
    out_of_balance,
    static_deflection,
)
from multilayer.wall.stack import Stack

#: the correction |dᵏ|, relative to the reference's displacement |Dᵏ|, the iteration stops at: the wall under P⁰
#: on the reference found sits on the mesh to that (a nearly incompressible band's out-of-balance force is
#: κ/σ times its displacement's error, relative to its size: 10⁻⁴ at an error of 10⁻⁹ cm, κ/σ ~ 10⁵ per cm)
PRECISION = 1e-10
#: the first step of the pressure, as a fraction of initial.pressure, whose reference is found before the next:
#: the references at growing pressures, each from the last two (a soft wall is imaged far from its reference,
#: whose forward solves from the mesh do not converge); halved where a step fails, doubled after a success
FIRST_STEP = 0.25
SMALLEST_STEP = 2.0**-6
#: iterations allowed (fixed point and Newton's method together), for each step of the pressure
MAX_ITERATIONS = 60
#: a correction that has not shrunk below this fraction of the one :data:`PATIENCE` iterations before: the fixed
#: point stalls (or diverges), and Newton's method takes over
STALL = 0.9
PATIENCE = 4
#: the correction, relative to |Dᵏ|, below which the fixed point hands over to Newton's method on the
#: reference (its slowest modes, near held ends, contract by little more than nothing an iteration)
SWITCH = 1e-2
#: the tolerance of the fixed point's forward solves: it hands over to Newton's method at :data:`SWITCH`, which
#: needs no forward solve, so its corrections need not be exact
FORWARD_TOLERANCE = 1e-6
#: the relative step of the differences that apply Newton's Jacobian, its GMRES tolerance and iterations, the
#: halvings of a step that does not lower the out-of-balance force
DIFFERENCE = 1e-7
GMRES_TOLERANCE = 1e-8
GMRES_ITERATIONS = 100
HALVINGS = 8
#: the relaxation β of the plain step Dᵏ⁺¹ = Dᵏ − β dᵏ: the full step overshoots a wall that stiffens as it is
#: inflated (a hoop stretch λ under P⁰ multiplies the plain iteration's error by 1 − λ)
RELAXATION = 0.5
#: the iterations Anderson's acceleration combines (beyond the last)
DEPTH = 4

class PrestressError(ValueError):
    """The fixed point of the stress-free reference did not converge; ``iterations`` and ``residual`` (the last
    relative out-of-balance force of the mesh's state) say how far it went."""

    def __init__(self, message: str, iterations: int, residual: float):
        super().__init__(message)
        self.iterations = iterations
        self.residual = residual


@attrs.frozen(eq=False)
class Prestress:
    """The wall on its stress-free reference: the stack whose layers are unloaded at the mesh moved by
    ``reference`` (wall numbering), how many forward solves it took, and the relative out-of-balance force of
    d = 0 under P⁰ on it, each iteration's (the last one within the tolerance)."""

    stack: Stack
    reference: np.ndarray
    iterations: int
    residuals: tuple[float, ...]


def imbalance(stack: Stack, pressure: float, external: float) -> float:
    """‖f − f_int(0)‖ / ‖size of its terms‖ on the free DOFs: how far the mesh's state (d = 0) is from the
    equilibrium under the lumen pressure ``pressure`` and the outer ``external`` (dyn/cm²)."""
    f = _loads(stack, pressure, external)
    return at_trial(lambda x: out_of_balance(stack, f, x), np.zeros(stack.free.size))[2]  # nan: out of range


def prestress(stack: Stack, pressure: float, external: float, stats: SolverStats | None = None,
              tolerance: float = TOLERANCE, max_iterations: int = MAX_ITERATIONS) -> Prestress:
    """The stress-free reference under which the wall of ``stack`` (built on the imaged mesh, unloaded there)
    is in equilibrium on the mesh under the lumen pressure ``pressure`` and the outer ``external``
    (dyn/cm²), by the backward displacement fixed point (module docstring), the pressure in steps
    (:data:`FIRST_STEP`).  ``tolerance``: the relative out-of-balance force it stops at, and its forward solves'
    (``static_deflection``'s) tolerance.

    Raises
    ------
    PrestressError
        When the wall has no layer that takes a reference, or the iteration does not converge.
    """
    takers = [p.where for p in stack.space.placements if type(p.layer).takes_reference()]
    if not takers:
        raise PrestressError("no layer of the wall takes a stress-free reference off its mesh (a finite-strain "
                             "layer: neo-hookean, hgo, neo-hookean-membrane, hgo-membrane)", 0, np.inf)
    stats = SolverStats() if stats is None else stats
    D, last, done, step = np.zeros(stack.space.ndofs), None, 0.0, FIRST_STEP
    iterations, found = 0, None
    while done < 1.0:
        step = min(step, 1.0 - done)
        guess = D if last is None else D + (step / last[1]) * (D - last[0])  # the secant predictor
        try:
            found = _reference(stack, (done + step) * pressure, (done + step) * external, stack.zero_fixed(guess),
                               stats, tolerance, max_iterations)
        except (PrestressError, LayerError) as exc:
            if step <= SMALLEST_STEP:
                if isinstance(exc, PrestressError):
                    raise PrestressError(f"{exc} (at {done + step:.4g} of initial.pressure, in steps down to "
                                         f"{SMALLEST_STEP:g} of it)", iterations + exc.iterations,
                                         exc.residual) from exc
                raise
            step /= 2.0
            continue
        iterations += found.iterations
        last, D, done = (D, step), found.reference, done + step
        step *= 2.0
    return attrs.evolve(found, iterations=iterations)


def _reference(stack: Stack, pressure: float, external: float, start: np.ndarray, stats: SolverStats,
               tolerance: float, max_iterations: int) -> Prestress:
    """The reference under ``pressure`` and ``external`` (one step of :func:`prestress`), its iteration from
    the reference ``start``: the backward displacement fixed point, then Newton's method."""
    free = stack.free
    D = start.copy()
    guess = None
    current = stack.on_reference(D)
    residuals = [imbalance(current, pressure, external)]
    corrections: list[float] = []
    history: list[tuple[np.ndarray, np.ndarray]] = []
    while not (residuals[-1] <= tolerance or corrections and corrections[-1] <= SWITCH * np.max(np.abs(D))):
        k = len(corrections)
        if k == max_iterations:
            raise _refused(f"did not converge in {k} iterations", residuals, corrections)
        try:
            d = static_deflection(current, pressure, external, stats, tolerance=max(tolerance, FORWARD_TOLERANCE),
                                  start=guess, steps_from=D)
        except (NewtonError, Unsettled) as exc:
            raise _refused(f"stopped at iteration {k + 1}: the wall under initial.pressure on the reference "
                           f"found so far is not solved ({exc})", residuals, corrections) from exc
        corrections.append(float(np.max(np.abs(d))))
        if k >= PATIENCE and corrections[-1] > STALL * corrections[-1 - PATIENCE]:
            break  # the fixed point stalls: Newton's method from here
        x, r = D[free].copy(), -d[free]
        D[free] = x + RELAXATION * r - _anderson(history, x, r)
        # the next solve starts from this one's wall moved with its reference (the plain step halves it)
        guess = d.copy()
        guess[free] += D[free] - x
        history = (history + [(x, r)])[-1 - DEPTH:]
        current = stack.on_reference(D)
        residuals.append(imbalance(current, pressure, external))
    while not (residuals[-1] <= tolerance or corrections and corrections[-1] <= PRECISION * np.max(np.abs(D))):
        if len(corrections) == max_iterations:
            raise _refused(f"did not converge in {max_iterations} iterations", residuals, corrections)
        D, current, step, residual = _newton_step(stack, current, D, _loads(stack, pressure, external), stats)
        if not residual < residuals[-1]:
            raise _refused(f"stopped at iteration {len(corrections) + 1}: Newton's correction of the reference "
                           f"does not lower the out-of-balance force", residuals, corrections)
        corrections.append(step)
        residuals.append(residual)
    return Prestress(current, D, len(corrections), tuple(residuals))


def _loads(stack: Stack, pressure: float, external: float) -> np.ndarray:
    """The loads on the mesh's wall (d = 0): ``pressure`` on the lumen, ``external`` on the outer surface."""
    return loads(stack, pressure, external, np.zeros(stack.space.ndofs))


def _newton_step(stack: Stack, current: Stack, D: np.ndarray, f: np.ndarray,
                 stats: SolverStats) -> tuple[np.ndarray, Stack, float, float]:
    """One Newton correction of the reference D for R(D) = f − f_int(0; D) = 0 (free DOFs), its Jacobian
    ∂f_int(0; D)/∂D applied by differences of the forces and solved by GMRES, preconditioned by −K_T(0; D)
    (moving the reference by δD is moving the wall by −δD, to first order in the strain), the step halved
    until R falls.  Returns (D, its stack, max |δD|, the relative out-of-balance force)."""
    free = stack.free
    zero = np.zeros(stack.space.ndofs)
    r, size = out_of_balance(current, f, zero[free])
    before = relative(r, size)
    g0 = current.force(zero)[free]
    factors = factorize(current.tangent(zero).tocsr()[free][:, free], stats)
    scale = max(float(np.max(np.abs(D))), 1e-300)

    def jacobian(v: np.ndarray) -> np.ndarray:
        eps = DIFFERENCE * scale / max(float(np.max(np.abs(v))), 1e-300)
        moved = D.copy()
        moved[free] += eps * v
        return (stack.on_reference(moved).force(zero)[free] - g0) / eps

    J = LinearOperator((free.size, free.size), matvec=jacobian)
    M = LinearOperator((free.size, free.size), matvec=lambda v: -factors.solve(v))
    delta, info = gmres(J, r, M=M, rtol=GMRES_TOLERANCE, atol=0.0, restart=GMRES_ITERATIONS,
                        maxiter=1)
    for _ in range(HALVINGS):
        trial = D.copy()
        trial[free] += delta
        try:
            moved = stack.on_reference(trial)
        except LayerError:  # a reference that folds: a shorter step
            delta = 0.5 * delta
            continue
        _, _, h = at_trial(lambda x: out_of_balance(moved, f, x), zero[free])  # (nan out of the layers' range)
        if h < before:
            return trial, moved, float(np.max(np.abs(delta))), h
        delta = 0.5 * delta
    return D, current, 0.0, before


def _anderson(history: list[tuple[np.ndarray, np.ndarray]], x: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Anderson's acceleration: (ΔX + β ΔR) γ, γ the least-squares fit of the residual r by the differences ΔR of
    the last iterations' (``history``: their iterates and residuals), to be taken from the relaxed step."""
    if not history:
        return np.zeros_like(x)
    dX = np.column_stack([x - h[0] for h in history])
    dR = np.column_stack([r - h[1] for h in history])
    gamma = np.linalg.lstsq(dR, r, rcond=None)[0]
    return (dX + RELAXATION * dR) @ gamma


def _refused(why: str, residuals: list[float], corrections: list[float]) -> PrestressError:
    seen = ", ".join(f"{c:.2e}" for c in corrections[-6:])
    return PrestressError(f"the wall's stress-free reference (the backward displacement fixed point) {why}; "
                          f"relative out-of-balance force of the imaged wall {residuals[-1]:.2e} (tolerance "
                          f"reached: no); last corrections |dᵏ| {seen or 'none'} cm", len(corrections), residuals[-1])
