"""``windkessel``: the three-element RCR Windkessel at an end, coupled implicitly.

    p = P_c + R_p Q,        C dP_c/dt = Q − (P_c − P_d)/R_d,

Q the outward flux through the end (the geometry's measure), P_c the
capacitor's pressure (the condition's own state), P_d the distal pressure.
The capacitor equation is discretized by the step's own time scheme, at the
scheme's test level P̄_c = Σβ_k P_c^{n+1−k} (:mod:`multilayer.numerics.timescheme`):

    C Σα_k P_c^{n+1−k} = Δt (Q̄ − (P̄_c − P_d)/R_d),

so P̄_c = a + b Q̄ with b = Δt/(C α₀/β₀ + Δt/R_d) and the end's mean pressure
is p̄ = a + (b + R_p) Q̄: the capacitor is eliminated into the end's
resistance (a rank-one term of the fluid's matrix, its entries in the
sparsity pattern from setup), no sub-iterations, no stability limit at any
R_p, C, R_d.  Energy: testing the capacitor equation with P̄_c gives

    −Δt p̄ Q̄ = −Δt P_d (P̄_c − P_d)/R_d − Δt R_p Q̄² − Δt (P̄_c − P_d)²/R_d − numerical − Δ(½ C P_c²),

the distal pressure's work (``work.<end>``), the dissipation of R_p and R_d
and the scheme's numerical dissipation (``dissipation.<end>.proximal``,
``.distal``, ``.numerical``: 0 for Crank–Nicolson) and the change of the
capacitor's energy (``stored.<end>``; BDF2's G-norm).  Units in the planar
channel are per unit depth: Q in cm²/s, R in dyn·s/cm⁴, C in cm⁴/dyn.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import attrs

from multilayer.boundary.contract import BoundaryCondition, EndTraction
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import BoundaryPlugin, Param


@attrs.frozen
class CapacitorState:
    """P_c at a time level, and what the step that made it stored and dissipated."""

    pressure: float  #: P_c (dyn/cm²)
    stored: float  #: the capacitor's energy as the scheme's identity carries it (½ C P_c², BDF2's G-norm)
    mean: float = 0.0  #: P̄_c of the step that made this state
    numerical: float = 0.0  #: the scheme's numerical dissipation in that step


class Windkessel(BoundaryCondition):
    """An RCR Windkessel: proximal resistance R_p, capacitance C, distal resistance R_d, distal pressure P_d.

    >>> from multilayer.numerics.timescheme import named
    >>> w = Windkessel(proximal=10.0, capacitance=1e-3, distal=100.0)
    >>> be = named("backward-euler")
    >>> t = w.traction((0.0, 0.1), 0.1, be, [w.initial_state()])
    >>> round(t.resistance - 10.0, 12) == round(0.1 / (1e-3 + 0.1 / 100.0), 12)
    True
    """

    implicit = True

    def __init__(self, proximal: float, capacitance: float, distal: float, distal_pressure: float = 0.0,
                 initial_pressure: float | None = None):
        if not proximal >= 0.0 or not capacitance > 0.0 or not distal > 0.0:
            raise ValueError("expected proximal >= 0, capacitance > 0 and distal > 0")
        self.proximal, self.capacitance, self.distal = float(proximal), float(capacitance), float(distal)
        self.distal_pressure = float(distal_pressure)
        self.initial_pressure = self.distal_pressure if initial_pressure is None else float(initial_pressure)

    def __repr__(self) -> str:
        return (f"Windkessel(proximal={self.proximal!r}, capacitance={self.capacitance!r}, distal={self.distal!r}, "
                f"distal_pressure={self.distal_pressure!r}, initial_pressure={self.initial_pressure!r})")

    def _energy(self, p: float) -> float:
        return 0.5 * self.capacitance * p * p

    def initial_state(self) -> CapacitorState:
        return CapacitorState(self.initial_pressure, self._energy(self.initial_pressure), self.initial_pressure)

    def _affine(self, dt: float, scheme: Any, history: Sequence[CapacitorState]) -> tuple[float, float]:
        """(a, b) of P̄_c = a + b Q̄ for the step."""
        C, Rd = self.capacitance, self.distal
        h = scheme.history([s.pressure for s in history])  # Σα_k P_k = (α₀/β₀) P̄ + h
        denominator = C * scheme.inertia + dt / Rd
        return (dt * self.distal_pressure / Rd - C * h) / denominator, dt / denominator

    def traction(self, window: tuple[float, float], dt: float, scheme: Any,
                 history: Sequence[CapacitorState]) -> EndTraction:
        a, b = self._affine(dt, scheme, history)
        return EndTraction(a, b + self.proximal)

    def advance(self, traction: EndTraction, flux: float, dt: float, scheme: Any,
                history: Sequence[CapacitorState]) -> CapacitorState:
        a, b = self._affine(dt, scheme, history)
        mean = a + b * flux
        old = [s.pressure for s in history]
        new = float(scheme.new_level(mean, old))
        levels = [new, *old]
        return CapacitorState(new, scheme.stored(self._energy, levels), mean, scheme.numerical(self._energy, levels))

    def state_to_data(self, state: CapacitorState) -> dict[str, float]:
        """The capacitor's state as data (a checkpoint's): its four numbers."""
        return {k: float(v) for k, v in attrs.asdict(state).items()}

    def state_from_data(self, data: Any) -> CapacitorState:
        fields = [f.name for f in attrs.fields(CapacitorState)]
        if not isinstance(data, dict) or sorted(data) != sorted(fields) or not all(
                isinstance(v, float) for v in data.values()):
            raise ValueError(f"a Windkessel's state should be the numbers {', '.join(fields)}")
        return CapacitorState(**data)

    def energy(self, end: str, state: CapacitorState) -> dict[str, float]:
        return {f"stored.{end}": state.stored}

    def columns(self, end: str, state: CapacitorState) -> dict[str, float]:
        return {f"end.{end}.P_c": state.pressure}

    def ledger(self, end: str, traction: EndTraction, flux: float, dt: float, old: CapacitorState,
               new: CapacitorState) -> tuple[dict[str, float], dict[str, float]]:
        excess = new.mean - self.distal_pressure
        work = {f"work.{end}": -dt * self.distal_pressure * excess / self.distal}
        dissipation = {f"dissipation.{end}.proximal": dt * self.proximal * flux * flux,
                       f"dissipation.{end}.distal": dt * excess * excess / self.distal,
                       f"dissipation.{end}.numerical": new.numerical}
        return work, dissipation


@hookimpl
def multilayer_boundaries():
    return [BoundaryPlugin(
        name="windkessel", factory=Windkessel,
        params=(Param("proximal", "R_p", "dyn·s/cm⁴ per unit depth (planar), dyn·s/cm⁵ (tube)", ge=0.0,
                      doc="proximal resistance, between the end and the capacitor"),
                Param("capacitance", "C", "cm⁴/dyn per unit depth (planar), cm⁵/dyn (tube)", gt=0.0,
                      doc="compliance of the distal vessels"),
                Param("distal", "R_d", "dyn·s/cm⁴ per unit depth (planar), dyn·s/cm⁵ (tube)", gt=0.0,
                      doc="distal resistance, from the capacitor to the venous side"),
                Param("distal_pressure", "P_d", "dyn/cm²", default=0.0, doc="pressure beyond the distal resistance"),
                Param("initial_pressure", "P_c⁰", "dyn/cm²", default=None,
                      doc="the capacitor's pressure at t = 0 (default: P_d)")),
        doc="Three-element RCR Windkessel, its capacitor discretized by the step's time scheme, coupled implicitly.")]
