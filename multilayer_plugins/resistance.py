"""``resistance``: an end whose pressure follows the flow through it, p = P_ref + R·Q.

Q is the outward flux through the end in the geometry's measure (cm²/s per
unit depth in the planar channel, cm³/s in a tube), so R is in dyn·s/cm⁴ per
unit depth (planar) or dyn·s/cm⁵ (tube).  Coupled implicitly: the fluid
carries R (∫q·n)(∫ū·n) in its matrix (docs/boundary-conditions.md).  Over a
step the end takes Δt R Q̄² out of the fluid (column
``dissipation.<end>.resistance``) and P_ref does the work −Δt P_ref Q̄
(``work.<end>``).  An outlet with R = ρ_f c / A (the characteristic
impedance of the vessel: c its wave speed, A its section) lets a wave leave
with little reflection.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from multilayer.boundary.contract import BoundaryCondition, EndTraction
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import BoundaryPlugin, Param


class Resistance(BoundaryCondition):
    """p = ``pressure`` + ``resistance`` · Q at an end.

    >>> Resistance(resistance=100.0, pressure=5.0).traction((0.0, 1e-3), 1e-3, None, [None])
    EndTraction(pressure=5.0, resistance=100.0, flux=None)
    """

    implicit = True

    def __init__(self, resistance: float, pressure: float = 0.0):
        if not resistance >= 0.0:
            raise ValueError(f"the resistance must be >= 0, got {resistance!r}")
        self.resistance, self.pressure = float(resistance), float(pressure)

    def __repr__(self) -> str:
        return f"Resistance(resistance={self.resistance!r}, pressure={self.pressure!r})"

    def traction(self, window: tuple[float, float], dt: float, scheme: Any, history: Sequence[Any]) -> EndTraction:
        return EndTraction(self.pressure, self.resistance)

    def at_rest(self) -> bool:
        return self.resistance == 0.0 and self.pressure == 0.0


@hookimpl
def multilayer_boundaries():
    return [BoundaryPlugin(
        name="resistance", factory=Resistance,
        params=(Param("resistance", "R", "dyn·s/cm⁴ per unit depth (planar), dyn·s/cm⁵ (tube)", ge=0.0,
                      doc="p − P_ref per unit of outward flux"),
                Param("pressure", "P_ref", "dyn/cm²", default=0.0, doc="the pressure at zero flux")),
        doc="p = P_ref + R·Q: a resistance coupled implicitly (e.g. the characteristic impedance of an outlet).")]
