"""``flow-rate``: a prescribed flow rate Q(t) through an end, imposed as a defective condition.

The case gives the flow INTO the channel through the end (at the inlet, the
flow that enters at z = 0), as any load kind: a number, a formula in t or a
table ``{model = "sine", ...}`` (:mod:`multilayer.functions.loads`), in
cm²/s per unit depth in the planar channel, cm³/s in a tube.  A flux alone
does not fix the velocity on the end, so the condition is defective: the
end's mean pressure λ is one more unknown of the fluid's step, a Lagrange
multiplier (Formaggia, Gerbeau, Nobile & Quarteroni 2002), with the
constraint that each new level carries the prescribed flow,

    ∫_Γ J u^{n+1}·n = −Q_in(tⁿ⁺¹)          (n the outward normal),

imposed on the step's test level ū = Σβ_k u^{n+1−k} with the old levels'
fluxes on the right (:mod:`multilayer_plugins.channel.ends`): the flux is
data on the velocity, like a Dirichlet value, not a load averaged over the
step.  The fluid appends λ after (ū, p̄) and borders its matrix
symmetrically; the couplers see only a larger system.  Over a step the end
hands the fluid −Δt λ Q̄_out = Δt λ Q̄_in, the work of the prescribed flow
(column ``work.<end>``); the fluid writes λ and Q̄_out as ``end.<end>.p``
and ``end.<end>.Q``.  The condition's state is the multiplier of the step
that made it (None before the first step).  docs/boundary-conditions.md, "A prescribed flow rate".
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from multilayer.boundary.contract import BoundaryCondition, BuildContext, EndTraction
from multilayer.functions.loads import LoadSpec, PressureLoad
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import MODEL, BoundaryPlugin, Param
from multilayer_plugins.pressure import history_from_spec

#: the unit of a flow rate: the geometry's measure of a section times a velocity
UNIT = "cm²/s per unit depth (planar), cm³/s (tube)"


class FlowRate(BoundaryCondition):
    """The inflow Q_in(t) through an end; its mean pressure λ is solved for.

    >>> from multilayer.functions.loads import SinePressure
    >>> FlowRate(SinePressure(amplitude=2.0, frequency=1.0)).flux(0.25, [None])
    -2.0
    """

    constraint = True

    def __init__(self, flow: PressureLoad):
        self.flow = flow

    def __repr__(self) -> str:
        return f"FlowRate({self.flow!r})"

    def traction(self, window: tuple[float, float], dt: float, scheme: Any, history: Sequence[Any]) -> EndTraction:
        """No pressure of its own: the end's mean pressure is the multiplier λ."""
        return EndTraction(0.0)

    def flux(self, time: float, history: Sequence[Any]) -> float:
        """The outward flux at ``time``: minus the inflow."""
        return -float(self.flow.value(time))

    def advance(self, traction: EndTraction, flux: float, dt: float, scheme: Any, history: Sequence[Any]) -> float:
        """The multiplier λ of the step (``traction.pressure`` once solved): the end's mean pressure."""
        return traction.pressure

    def histories(self) -> tuple[PressureLoad, ...]:
        return (self.flow,)

    def resolved(self) -> dict[str, Any]:
        return {MODEL: "flow-rate", "flow": self.flow.to_dict()}


def flow_rate_end(context: BuildContext, flow: Any) -> FlowRate:
    """The end from its ``flow`` as the case writes it (a table's file relative to the case).

    Raises CaseError at the key path of the flow (``loads.inlet.flow.amplitude``...).
    """
    return FlowRate(history_from_spec(flow, f"{context.path}.flow", context, "flow rate", UNIT))


@hookimpl
def multilayer_boundaries():
    return [BoundaryPlugin(
        name="flow-rate", factory=flow_rate_end, context=True,
        params=(Param("flow", "Q_in", UNIT, type=LoadSpec,
                      doc="the flow Q(t) through the end, positive into the channel, as a load kind"),),
        doc="A prescribed flow rate Q(t) into the channel; the end's mean pressure is a Lagrange multiplier.")]
