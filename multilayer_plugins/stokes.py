"""``stokes``: the unsteady Stokes fluid — ``navier-stokes`` without the advection terms.

Everything else of theory §6 A2 stays, the moving-domain term ρ_f/2 ∫ (v/R) u·q
included: it belongs to the moving domain, not to advection.
"""

from __future__ import annotations

from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import FluidPlugin
from multilayer_plugins.channel import PARAMS, Stokes


@hookimpl
def multilayer_fluids() -> list[FluidPlugin]:
    """The ``stokes`` fluid."""
    return [
        FluidPlugin(
            name="stokes",
            factory=Stokes,
            params=PARAMS,
            doc="Unsteady Stokes on the moving channel (Navier–Stokes without advection).",
        )
    ]
