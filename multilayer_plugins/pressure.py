"""Prescribed pressure at an open end: ``constant``, ``cosine-pulse``, ``sine``, ``table``, ``formula``.

The end's mean normal stress over a step is the pressure history's average
over the scheme's window (:mod:`multilayer.functions.loads`), independent of
the flow: p̄ = P̄, no resistance.  The fluid receives −Δt P̄ Q̄ through the
end (column ``work.<end>``).  A case writes the end as a number (constant),
a string (formula in t) or a table ``{model = "...", ...}`` with the load's
parameters.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from multilayer.boundary.contract import BoundaryCondition, BuildContext, EndTraction
from multilayer.functions.domain import Domain, judge
from multilayer.functions.loads import (
    KINDS,
    PRESSURE_UNIT,
    FormulaPressure,
    PressureLoad,
    is_zero,
    load_from_spec,
)
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.problems import CaseError
from multilayer.plugin.records import BoundaryPlugin


class PressureEnd(BoundaryCondition):
    """A prescribed pressure history P(t) at one end (dyn/cm²).

    >>> from multilayer.functions.loads import ConstantPressure
    >>> PressureEnd(ConstantPressure(5.0)).traction((0.0, 1.0), 1.0, None, [None])
    EndTraction(pressure=5.0, resistance=0.0, flux=None)
    """

    implicit = False

    def __init__(self, load: PressureLoad):
        self.load = load

    @property
    def model(self) -> str:
        """The load's name in a case file (``constant``, ``cosine-pulse``, ...)."""
        return self.load.model

    def __repr__(self) -> str:
        return f"PressureEnd({self.load!r})"

    def traction(self, window: tuple[float, float], dt: float, scheme: Any, history: Sequence[Any]) -> EndTraction:
        return EndTraction(self.load.average(*window))

    def at_rest(self) -> bool:
        return is_zero(self.load)

    def histories(self) -> tuple[PressureLoad, ...]:
        return (self.load,)

    def resolved(self) -> dict[str, Any]:
        return self.load.to_dict()


def history_from_spec(spec: Any, path: str, context: BuildContext, quantity: str = "pressure",
                      unit: str = PRESSURE_UNIT) -> PressureLoad:
    """A function of t as the case writes it at ``path`` (a load kind), a formula judged finite over the run.

    A table's file is read relative to the case (``context.base_dir``).
    Raises CaseError with the key path (``loads.inlet.duration``...), as the load kinds do.
    """
    load = load_from_spec(spec, path, context.base_dir, context.constants, quantity, unit)
    if isinstance(load, FormulaPressure):
        where = path if isinstance(spec, str) else f"{path}.expr"
        problem = judge(load.formula, where, Domain({"t": (0.0, context.end)}))
        if problem is not None:
            raise CaseError([problem])
    return load


def pressure_end(context: BuildContext, **params: Any) -> PressureEnd:
    """The end as the case writes it (``context.spec``), its formula judged finite over the run."""
    return PressureEnd(history_from_spec(context.spec, context.path, context))


_DOCS = {
    "constant": "A constant pressure (a number in the case file).",
    "cosine-pulse": "P_max/2 (1 − cos 2πt/t_max) for 0 ≤ t ≤ t_max, then 0: the reference pulse.",
    "sine": "mean + amplitude sin(2πft + φ).",
    "table": "Piecewise-linear P(t) from a CSV file t,p, optionally periodic.",
    "formula": "A formula in t (a string in the case file).",
}


@hookimpl
def multilayer_boundaries():
    return [BoundaryPlugin(name=kind, factory=pressure_end, params=KINDS[kind], doc=_DOCS[kind], context=True)
            for kind in KINDS]
