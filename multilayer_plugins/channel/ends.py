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

An end whose condition prescribes its flux (``constraint``: a flow rate)
has instead an unknown of its own, appended after (u, p): its mean
pressure λ_e, a Lagrange multiplier (a defective condition, Formaggia,
Gerbeau, Nobile & Quarteroni 2002).  With s_e = −J_e ℓ_e, the outward flux
functional (Q_e = s_e·u), the step carries

    velocity rows  + λ_e s_e        (the traction −λ_e n: a pressure λ_e moved to the left),
    row of λ_e     s_eᵀ ū = Q̄_e,   Q̄_e = β₀ Q_e(tⁿ⁺¹) + Σ_{k≥1} β_k s_e·u^{n+1−k},

a symmetric border [s_e; s_eᵀ 0] of the matrix, in the pattern from setup.
Q̄_e is the test level of the prescribed flux: the new level gets exactly
s_e·u^{n+1} = Q_e(tⁿ⁺¹), whatever the old levels carry (a step averaging
Q over its window instead would leave Crank–Nicolson's undamped mode
(−1)ⁿ in the level fluxes, and in λ a wrong first-order pressure).
Testing with ū, the end hands the fluid −Δt λ_e Q̄_e, as a pressure λ_e would.

Every end's P_e (or λ_e) is a total pressure p + ½ρ_f|u|² for the flow
through it, by the skew-symmetric advection; a Navier–Stokes fluid with
static-pressure ends carries instead the convective term of
:mod:`multilayer_plugins.channel.end_convection` on both ends, whatever
their conditions (its entries in the pattern from setup too).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from multilayer.boundary.contract import BoundaryCondition, EndTraction
from multilayer.fluid.contract import ENDS
from multilayer.numerics.assembly.pattern import Pattern
from multilayer_plugins.channel import forms
from multilayer_plugins.channel.channel import Channel
from multilayer_plugins.channel.end_convection import EndConvection


class TractionFree(BoundaryCondition):
    """An end left out of the fluid's setup: no traction (p̄ = 0), the natural condition."""

    def traction(self, window, dt, scheme, history) -> EndTraction:
        return EndTraction(0.0)

    def at_rest(self) -> bool:
        return True


class Ends:
    """The two ends of a channel with their conditions, load vectors and, for implicit and flow-rate ones,
    pattern slots.

    Parameters
    ----------
    channel : Channel
        The reference channel (its ``inlet`` and ``outlet`` facet bases).
    conditions : mapping
        The condition of each end by name (``inlet``, ``outlet``); a missing end is traction-free.
    density : float
        ρ_f (g/cm³), for the static-pressure ends' convective term.
    backflow : float or None
        None: total-pressure ends (no convective term); β ≥ 0: static-pressure ends with the
        backflow term of strength β (:mod:`multilayer_plugins.channel.end_convection`).
    """

    def __init__(self, channel: Channel, conditions: Mapping[str, BoundaryCondition], density: float = 1.0,
                 backflow: float | None = None):
        self.geometry = channel.geometry
        self.conditions = {end: conditions.get(end) or TractionFree() for end in ENDS}
        bases = {"inlet": channel.inlet, "outlet": channel.outlet}
        self.loads = {end: forms.dynamic_pressure.assemble(bases[end], J=1.0) for end in ENDS}
        self.implicit = [end for end in ENDS if self.conditions[end].implicit]
        #: the ends that prescribe their flux, and the unknown of each one's multiplier λ_e (after u and p)
        self.multipliers = {end: channel.ndofs + k
                            for k, end in enumerate(e for e in ENDS if self.conditions[e].constraint)}
        #: velocity DOFs where the load vector of each implicit or constrained end is not zero
        self.support = {end: np.flatnonzero(self.loads[end]) for end in ENDS
                        if end in self.implicit or end in self.multipliers}
        self._slots: dict[str, np.ndarray] = {}
        self._border: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        #: the static-pressure ends' convective term (None: total-pressure ends)
        self.convection = None if backflow is None else EndConvection(bases, density, backflow)

    def _rank_one(self, end: str) -> tuple[np.ndarray, np.ndarray]:
        """(rows, columns) of an implicit end's block (J ℓ)(J ℓ)ᵀ."""
        dofs = self.support[end]
        return np.repeat(dofs, dofs.size), np.tile(dofs, dofs.size)

    def _border_entries(self, end: str) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
        """(rows, columns) of a constrained end's column s_e and of its row s_eᵀ."""
        dofs = self.support[end]
        at = np.full(dofs.size, self.multipliers[end])
        return (dofs, at), (at, dofs)

    def entries(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """(rows, columns) of the rank-one blocks of the implicit ends and of the constrained ends' borders
        (column and row of each λ_e), for the sparsity pattern."""
        return ([self._rank_one(end) for end in self.implicit]
                + [part for end in self.multipliers for part in self._border_entries(end)]
                + (list(self.convection.entries.values()) if self.convection is not None else []))

    def place(self, pattern: Pattern) -> None:
        """Look up the slots of the rank-one blocks and of the borders in the step's pattern (once)."""
        for end in self.implicit:
            self._slots[end] = pattern.slots(*self._rank_one(end))
        for end in self.multipliers:
            column, row = self._border_entries(end)
            self._border[end] = (pattern.slots(*column), pattern.slots(*row))
        if self.convection is not None:
            self.convection.place(pattern)

    def initial_state(self) -> dict[str, Any]:
        return {end: c.initial_state() for end, c in self.conditions.items()}

    def tractions(self, times: tuple[float, float], dt: float, scheme: Any, history: Sequence[Any],
                  fields: Any) -> dict[str, EndTraction]:
        """Each end's p̄ = P + R Q̄ over the step [tⁿ, tⁿ⁺¹] = ``times``, its loads averaged over the scheme's
        window; a constrained end's test-level flux Q̄_e (module docstring).

        ``history`` holds the fluid's states at tⁿ, tⁿ⁻¹, ... (their ``ends`` and ``u``).
        """
        window = scheme.load_window(*times)
        tractions = {}
        for end, condition in self.conditions.items():
            states = [h.ends.get(end) for h in history]
            traction = condition.traction(window, dt, scheme, states)
            if traction.flux is not None:
                raise ValueError(f"the {end}'s condition {condition!r} sets EndTraction.flux: a flux is prescribed "
                                 f"through BoundaryCondition.flux, with constraint = True")
            if end in self.multipliers:
                if traction.pressure or traction.resistance:
                    raise ValueError(f"the {end} prescribes its flux: its pressure is the multiplier λ, "
                                     f"not {traction.pressure!r} + {traction.resistance!r} Q̄")
                levels = [condition.flux(times[1], states), *(self.flux(end, h.u, fields) for h in history)]
                traction = attrs.evolve(traction, flux=float(scheme.average(levels)))
            tractions[end] = traction
        return tractions

    def stretch(self, fields: Any, end: str) -> float:
        """J_e of the end in the step's domain, moved to the geometry's volume element."""
        return self.geometry.stretch(fields.J_in if end == "inlet" else fields.J_out)

    def add_rhs(self, rhs: np.ndarray, tractions: Mapping[str, EndTraction], fields: Any) -> None:
        """rhs += P_e J_e ℓ_e for each end (the velocity rows); rhs_λe = Q̄_e for each constrained end."""
        nu = self.loads["inlet"].size
        rhs[:nu] += (tractions["inlet"].pressure * self.stretch(fields, "inlet") * self.loads["inlet"]
                     + tractions["outlet"].pressure * self.stretch(fields, "outlet") * self.loads["outlet"])
        for end, k in self.multipliers.items():
            rhs[k] = tractions[end].flux

    def add_matrix(self, data: np.ndarray, tractions: Mapping[str, EndTraction], fields: Any,
                   advecting: np.ndarray | None = None) -> None:
        """data += R_e (J_e ℓ_e)(J_e ℓ_e)ᵀ for each implicit end with a resistance, and the border
        [s_e; s_eᵀ 0], s_e = −J_e ℓ_e, of each constrained end; with static-pressure ends, their convective
        term with the step's advecting velocity ``advecting`` (velocity DOFs; None for a Stokes fluid)."""
        for end in self.implicit:
            R = tractions[end].resistance
            if R:
                values = self.stretch(fields, end) * self.loads[end][self.support[end]]
                data[self._slots[end]] += R * np.outer(values, values).ravel()
        for end, (column, row) in self._border.items():
            s = -self.stretch(fields, end) * self.loads[end][self.support[end]]
            data[column] += s
            data[row] += s
        if self.convection is not None and advecting is not None:
            self.convection.add_matrix(data, advecting, self.stretches(fields))

    def stretches(self, fields: Any) -> dict[str, float]:
        """J_e of each end (:meth:`stretch`)."""
        return {end: self.stretch(fields, end) for end in ENDS}

    def convection_ledger(self, ubar: np.ndarray, advecting: np.ndarray | None, fields: Any, dt: float
                          ) -> dict[str, float]:
        """The static-pressure ends' convective term tested with ū, by column (none for total-pressure ends)."""
        if self.convection is None or advecting is None:
            return {}
        return self.convection.ledger(ubar, advecting, self.stretches(fields), dt)

    def resolve(self, tractions: Mapping[str, EndTraction], mean: np.ndarray) -> dict[str, EndTraction]:
        """The tractions as solved: a constrained end's pressure is its multiplier λ_e in ``mean``."""
        return {end: attrs.evolve(t, pressure=float(mean[self.multipliers[end]])) if end in self.multipliers else t
                for end, t in tractions.items()}

    def resistances(self, tractions: Mapping[str, EndTraction]) -> tuple[float, ...]:
        """The implicit ends' resistances: part of what a constant matrix is keyed by."""
        return tuple(tractions[end].resistance for end in self.implicit)

    def flux(self, end: str, u: np.ndarray, fields: Any) -> float:
        """Q_e = −J_e ℓ_e·u: the outward flux through the end (cm²/s per unit depth, cm³/s in a tube)."""
        return -(self.stretch(fields, end) * float(self.loads[end] @ u[: self.loads[end].size]))

    def fluxes(self, u: np.ndarray, fields: Any) -> dict[str, float]:
        """The outward flux through each end."""
        return {end: self.flux(end, u, fields) for end in ENDS}

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
