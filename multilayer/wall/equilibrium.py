"""The wall's static equilibrium under a fluid at rest at a uniform pressure: a start without ringing.

A case with ``[initial] pressure = P⁰`` starts with the fluid at rest at the
uniform pressure P⁰ and the wall already deflected under it (an artery
inflated at its diastolic pressure), rather than at rest undeformed with the
loads switched on at full size at t = 0.  The wall solves f_int(d) = f with its
essential DOFs held (K d = f for a linear wall), where f is P⁰ on the lumen and the external pressure
at t = 0 on the outer surface.  The fluid's pressure acts on the lumen's
deformed place r = R + η: under a measure c·rᵏ its work vector is
P⁰ ∫ ψ ((R + η)/R)ᵏ dA, so a tube's (k = 1) depends on η and the
deflection is iterated to round-off; a planar one (k = 0) is one solve.
Each solve under a given f is Newton's loop (:mod:`multilayer.numerics.newton`):
one back-substitution with the factors of K for a linear wall; for a wall
with a nonlinear layer, corrections with the tangent Σ_i K_T,i(d) from the
last deflection, until the residual is below the loop's tolerance (the
iteration of the moving lumen then stops at that tolerance, not at round-off).
Validation solves it too, to weigh the deflection against the channel
(:func:`multilayer.case.trial_walls.deflection_problems`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import skfem
from scipy.sparse.linalg import splu

from multilayer.numerics.linsolve import SolverStats, factorize
from multilayer.numerics.newton import TOLERANCE, NewtonError, newton
from multilayer.wall.stack import LUMEN, Stack

#: the relative change of the deflection at which the iteration of a measure moving with η stops
ROUND_OFF = 1e-14
#: a relative change that has stopped shrinking below this is the round-off floor of the solves (2e-14 on a thick
#: band under a fluid that pins its lumen's ends only), not a wall giving way: the iteration stops there too
FLOOR = 1e-10
#: iterations allowed (the fluid's share of the stiffness, P⁰ k/R against the wall's, is small)
MAX_ITERATIONS = 60
#: a nonlinear wall's first load step, as a fraction of the loads, when one solve does not reach the equilibrium
FIRST_STEP = 0.25
#: the smallest load step before the static solve is given up
SMALLEST_STEP = 2.0**-12


class Unsettled(ValueError):
    """The iteration of a measure moving with the lumen did not settle: the pressure on the moved lumen outgrows
    the wall's stiffness.  ``linear`` is its first iterate, the deflection under the load on the reference
    lumen (wall numbering)."""

    def __init__(self, message: str, linear: np.ndarray):
        super().__init__(message)
        self.linear = linear


def static_deflection(stack: Stack, pressure: float, external: float, stats: SolverStats | None = None,
                      start: np.ndarray | None = None, tolerance: float = TOLERANCE,
                      steps_from: np.ndarray | None = None) -> np.ndarray:
    """The wall displacement d (wall numbering, essential DOFs zero) with f_int(d) = f under the lumen pressure
    ``pressure`` and the outer surface's ``external`` (dyn/cm²).  ``stats``: where a nonlinear wall's Newton
    solves and factorizations are counted.  ``start``: where a nonlinear wall's iteration starts (default
    d = 0), e.g. the equilibrium under the last of a sequence of growing pressures (load steps: a large
    deformation that Newton's method does not reach from rest in one).  ``tolerance``: the relative residual a
    nonlinear wall's Newton iteration ends at (a nearly incompressible band under a large deformation has a
    round-off floor of about κ·10⁻¹⁶|d|/(h σ), κ its bulk modulus, σ its stress, h its cells' size, which may
    lie above the default).  ``steps_from``: where the load steps start when they are needed (default
    ``start``): the wall's equilibrium under no load (a prestressed wall's stress-free state,
    :mod:`multilayer.wall.prestress`, while ``start`` is a guess near the loaded one).

    A nonlinear wall that Newton's method does not bring from ``start`` to the equilibrium in one solve is
    brought there by load steps (:func:`_in_load_steps`).

    Raises
    ------
    Unsettled
        When the iteration of a measure moving with the lumen does not settle (a ValueError).
    NewtonError
        When a nonlinear wall's Newton iteration does not converge, even in the smallest load steps.
    """
    try:
        return _settle(stack, pressure, external, stats, start, tolerance)
    except NewtonError:
        if stack.linear:
            raise
    if steps_from is not None:
        steps_from = stack.zero_fixed(steps_from)
        load = np.linalg.norm(loads(stack, pressure, external, steps_from)[stack.free])
        unloaded = np.linalg.norm(stack.force(steps_from)[stack.free]) <= tolerance * load
        return _in_load_steps(stack, pressure, external, stats, steps_from, tolerance, unloaded, steps_from)
    return _in_load_steps(stack, pressure, external, stats, start, tolerance)


def _in_load_steps(stack: Stack, pressure: float, external: float, stats: SolverStats | None,
                   start: np.ndarray | None, tolerance: float, unloaded: bool = False,
                   steps_from: np.ndarray | None = None) -> np.ndarray:
    """The nonlinear wall's equilibrium under the loads scaled by s from 0 to 1, in steps that start at
    :data:`FIRST_STEP`, halve where Newton's iteration fails (down to :data:`SMALLEST_STEP`, then the failure is
    raised) and double after a success; each step from the last one's equilibrium (the first from ``start``,
    the equilibrium under no load solved from it, or ``start`` itself when ``unloaded``: a wall whose forces
    there are within the tolerance of the loads', where the relative residual of its unstressed layers would
    be round-off over round-off; from ``steps_from`` too when the equilibrium under no load is not reached
    from it, for that reason)."""
    if unloaded:
        d = start
    else:
        try:
            d = _settle(stack, 0.0, 0.0, stats, start, tolerance)
        except NewtonError:
            if steps_from is None:
                raise
            d = start  # near-unstressed layers' relative residual stays round-off over round-off: step from it
    done, step = 0.0, FIRST_STEP
    while done < 1.0:
        step = min(step, 1.0 - done)
        try:
            d = _settle(stack, (done + step) * pressure, (done + step) * external, stats, d, tolerance)
        except NewtonError:
            if step <= SMALLEST_STEP:
                raise
            step /= 2.0
            continue
        done += step
        step *= 2.0
    return d


def _settle(stack: Stack, pressure: float, external: float, stats: SolverStats | None, start: np.ndarray | None,
            tolerance: float) -> np.ndarray:
    """:func:`static_deflection` in one solve from ``start``."""
    space = stack.space
    k = space.lines[LUMEN].geometry.radial_power
    free = stack.free
    linear = stack.linear
    if linear:
        factors = splu(stack.stiffness.tocsc()[free][:, free]).solve
    settled = ROUND_OFF if linear else tolerance
    stats = SolverStats() if stats is None else stats
    d, previous, first = np.zeros(space.ndofs), np.inf, None
    if start is not None and not linear:
        d = stack.zero_fixed(start)
    for _ in range(MAX_ITERATIONS):
        f = loads(stack, pressure, external, d)
        new = np.zeros_like(d)
        if linear:
            new[free] = newton(None, lambda x, r: factors(r), None, linear=True, first=f[free]).x
        else:
            new[free] = newton(lambda x: out_of_balance(stack, f, x), lambda x, r: _tangent_solve(stack, x, r, stats),
                               d[free], stats=stats, tolerance=tolerance, what="the wall's static equilibrium").x
        change, size = np.max(np.abs(new - d)), np.max(np.abs(new))
        d = new
        first = new if first is None else first
        if k == 0 or change <= settled * size or previous <= change <= FLOOR * size:
            return d
        previous = change
    raise Unsettled(f"the wall's static equilibrium under initial.pressure = {pressure:g} did not settle in "
                    f"{MAX_ITERATIONS} iterations (last change {change:.3g} of {size:.3g} cm): the pressure on the moved "
                    f"lumen softens the wall (by P⁰/R per unit η) more than its stiffness holds; a smaller "
                    f"initial.pressure", first)


def loads(stack: Stack, pressure: float, external: float, d: np.ndarray) -> np.ndarray:
    """The loads at the wall ``d``: ``pressure`` on the lumen moved by it, ``external`` on the outer surface."""
    space = stack.space
    eta = space.restrictions[LUMEN] @ d
    return -external * space.line_load(space.outer_line) + space.prolongations[LUMEN] @ lumen_force(space, pressure, eta)


def _full(stack: Stack, x: np.ndarray) -> np.ndarray:
    d = np.zeros(stack.space.ndofs)
    d[stack.free] = x
    return d


def out_of_balance(stack: Stack, f: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """f − Σ_i f_i(d) on the free DOFs at their values ``x``, and the size of its terms (a nonlinear layer's
    :meth:`~multilayer.wall.layer.NonlinearForms.term_size`)."""
    d = _full(stack, x)
    internal = [m.force(d) for m in stack.matrices]
    r = f - sum(internal)
    size = np.abs(f) + sum(np.abs(term) if m.linear else m.term_size(term, d) for m, term in zip(stack.matrices, internal))
    return r[stack.free], size[stack.free]


def _tangent_solve(stack: Stack, x: np.ndarray, r: np.ndarray, stats: SolverStats) -> np.ndarray:
    """Σ_i K_T,i(d)⁻¹ r on the free DOFs (a one-off solve: each tangent factorized, full Newton)."""
    free = stack.free
    return factorize(stack.tangent(_full(stack, x)).tocsr()[free][:, free], stats).solve(r)


def lumen_force(space: Any, pressure: float, eta: np.ndarray) -> np.ndarray:
    """The force of a fluid at rest at ``pressure`` on the lumen moved by ``eta`` (both in the lumen line's
    numbering): pressure · ∫ ψ ((R + η)/R)ᵏ dA under the measure c·rᵏ."""
    line = space.lines[LUMEN]
    stretch = line.basis.interpolate(eta / line.radius)
    return pressure * skfem.asm(_moved_load, line.basis, stretch=stretch, k=line.geometry.radial_power)


@skfem.LinearForm
def _moved_load(v, w):
    return v * (1.0 + w["stretch"]) ** w["k"]


def lumen_compliance(stack: Stack) -> np.ndarray:
    """dη/dP on the lumen line (cm³/dyn, in the line's numbering): the deflection of the linear stack under a unit
    uniform pressure on its reference lumen, the outer surface free.

    Every layer of the stack carries its share, thin and thick: this is the static compliance that sets the long
    waves' speed (theory §11, c² = A/(ρ_f dA/dP)).  Near the ends the layers' end conditions hold the wall; far
    from them (a few wall thicknesses, or √(Rh) for a shell) it is the compliance of an endless wall.

    >>> from skfem import BilinearForm
    >>> from multilayer.geometry.contract import Geometry
    >>> from multilayer.wall.layer import LayerMatrices, ThinLayer
    >>> from multilayer.wall.stack import Stack, WallSpace
    >>> class Flat(Geometry):  # a planar measure, dV = dz dr
    ...     def weight(self, r):
    ...         return np.ones_like(np.asarray(r, dtype=float))
    >>> mass = BilinearForm(lambda eta, psi, w: eta * psi)
    >>> class Spring(ThinLayer):  # a wall on springs: a pressure P moves it by P/k, ends pinned
    ...     def forms(self, space):
    ...         M = mass.assemble(space.basis).tocsr()
    ...         return LayerMatrices(M, 0.0 * M, 2e5 * M)
    >>> stack = Stack.assemble(WallSpace.build([Spring()], Flat(), 6.0, 0.5, 24, 2))
    >>> compliance = lumen_compliance(stack)
    >>> z = stack.space.lines[LUMEN].z
    >>> float(compliance[np.argmin(abs(z - 3.0))] * 2e5).__round__(6), float(compliance[0])  # 1/k mid-way; pinned
    (1.0, 0.0)
    """
    space = stack.space
    free = stack.free
    f = space.line_load(LUMEN)
    d = np.zeros(space.ndofs)
    d[free] = splu(stack.stiffness.tocsc()[free][:, free]).solve(f[free])
    return space.restrictions[LUMEN] @ d
