"""The open ends of the channel (z = 0 and z = L) and what their conditions put into a step.

Each end Γ_e has a load vector ℓ_e = −∫_{Γ_e} q·n (assembled once, with the
geometry's measure) and, in the domain of a step, the stretch J_e of its
measure, so the outward flux of a velocity u is Q_e = −J_e ℓ_e·u.  The end's
condition (:class:`multilayer.boundary.contract.BoundaryCondition`) gives its
mean pressure over the step as p̄_e = P_e + R_e Q̄_e; the step then carries

    right-hand side  P_e J_e ℓ_e,       matrix  R_e (J_e ℓ_e)(J_e ℓ_e)ᵀ,

the second only for a condition that declares itself ``implicit``: its
entries are in the sparsity pattern from setup on, so the pattern, the
ordering and the reuse of factors are those of the run.  A rank-one term is
symmetric positive semidefinite: the end dissipates R_e Q̄_e² and the
scheme stays unconditionally stable at any R_e.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from multilayer.boundary.contract import BoundaryCondition, EndTraction
from multilayer.fluid.contract import ENDS
from multilayer.numerics.assembly.pattern import Pattern
from multilayer_plugins.channel import forms
from multilayer_plugins.channel.channel import Channel


class TractionFree(BoundaryCondition):
    """An end left out of the fluid's setup: no traction (p̄ = 0), the natural condition."""

    def traction(self, window, dt, scheme, history) -> EndTraction:
        return EndTraction(0.0)

    def at_rest(self) -> bool:
        return True


class Ends:
    """The two ends of a channel with their conditions, load vectors and, for implicit ones, pattern slots.

    Parameters
    ----------
    channel : Channel
        The reference channel (its ``inlet`` and ``outlet`` facet bases).
    conditions : mapping
        The condition of each end by name (``inlet``, ``outlet``); a missing end is traction-free.
    """

    def __init__(self, channel: Channel, conditions: Mapping[str, BoundaryCondition]):
        self.geometry = channel.geometry
        self.conditions = {end: conditions.get(end) or TractionFree() for end in ENDS}
        bases = {"inlet": channel.inlet, "outlet": channel.outlet}
        self.loads = {end: forms.dynamic_pressure.assemble(bases[end], J=1.0) for end in ENDS}
        self.implicit = [end for end in ENDS if self.conditions[end].implicit]
        #: velocity DOFs where each implicit end's load vector is not zero
        self.support = {end: np.flatnonzero(self.loads[end]) for end in self.implicit}
        self._slots: dict[str, np.ndarray] = {}

    def entries(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """(rows, columns) of the rank-one blocks of the implicit ends, for the sparsity pattern."""
        out = []
        for end in self.implicit:
            dofs = self.support[end]
            out.append((np.repeat(dofs, dofs.size), np.tile(dofs, dofs.size)))
        return out

    def place(self, pattern: Pattern) -> None:
        """Look up the slots of the rank-one blocks in the step's pattern (once)."""
        for end, (rows, cols) in zip(self.implicit, self.entries()):
            self._slots[end] = pattern.slots(rows, cols)

    def initial_state(self) -> dict[str, Any]:
        return {end: c.initial_state() for end, c in self.conditions.items()}

    def tractions(self, window: tuple[float, float], dt: float, scheme: Any,
                  history: Sequence[Mapping[str, Any]]) -> dict[str, EndTraction]:
        """Each end's p̄ = P + R Q̄ over the step; ``history`` the ends' states at tⁿ, tⁿ⁻¹, ..."""
        return {end: c.traction(window, dt, scheme, [h.get(end) for h in history])
                for end, c in self.conditions.items()}

    def stretch(self, fields: Any, end: str) -> float:
        """J_e of the end in the step's domain, moved to the geometry's volume element."""
        return self.geometry.stretch(fields.J_in if end == "inlet" else fields.J_out)

    def add_rhs(self, rhs: np.ndarray, tractions: Mapping[str, EndTraction], fields: Any) -> None:
        """rhs += P_e J_e ℓ_e for each end (the velocity rows)."""
        nu = self.loads["inlet"].size
        rhs[:nu] += (tractions["inlet"].pressure * self.stretch(fields, "inlet") * self.loads["inlet"]
                     + tractions["outlet"].pressure * self.stretch(fields, "outlet") * self.loads["outlet"])

    def add_matrix(self, data: np.ndarray, tractions: Mapping[str, EndTraction], fields: Any) -> None:
        """data += R_e (J_e ℓ_e)(J_e ℓ_e)ᵀ for each implicit end with a resistance."""
        for end in self.implicit:
            R = tractions[end].resistance
            if R:
                values = self.stretch(fields, end) * self.loads[end][self.support[end]]
                data[self._slots[end]] += R * np.outer(values, values).ravel()

    def resistances(self, tractions: Mapping[str, EndTraction]) -> tuple[float, ...]:
        """The implicit ends' resistances: part of what a constant matrix is keyed by."""
        return tuple(tractions[end].resistance for end in self.implicit)

    def fluxes(self, u: np.ndarray, fields: Any) -> dict[str, float]:
        """Q_e = −J_e ℓ_e·u: the outward flux through each end (cm²/s per unit depth, cm³/s in a tube)."""
        nu = self.loads["inlet"].size
        return {end: -(self.stretch(fields, end) * float(self.loads[end] @ u[:nu])) for end in ENDS}

    def advance(self, tractions: Mapping[str, EndTraction], fluxes: Mapping[str, float], dt: float, scheme: Any,
                history: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
        """The ends' states at tⁿ⁺¹."""
        return {end: c.advance(tractions[end], fluxes[end], dt, scheme, [h.get(end) for h in history])
                for end, c in self.conditions.items()}

    def energy(self, states: Mapping[str, Any]) -> dict[str, float]:
        """What the ends' conditions store, by ledger column."""
        out: dict[str, float] = {}
        for end, c in self.conditions.items():
            out.update(c.energy(end, states.get(end)))
        return out
