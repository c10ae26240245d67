"""``navier-stokes``: incompressible Navier–Stokes in the channel (theory §6, step A2).

ALE on the fixed reference channel, skew-symmetric advection with the
domain velocity of the structure step, static-pressure ends with a
backflow term (``ends``, ``backflow``; the seed's total pressure on
request), SUPG stabilization of convection with grad-div (``stabilization``,
``grad_div``).  The model lives in :mod:`multilayer_plugins.channel`; ``stokes`` is the same
class with the advection terms off.
"""

from __future__ import annotations

from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import FluidPlugin
from multilayer_plugins.channel import NAVIER_STOKES_PARAMS, NavierStokes


@hookimpl
def multilayer_fluids() -> list[FluidPlugin]:
    """The ``navier-stokes`` fluid."""
    return [
        FluidPlugin(
            name="navier-stokes",
            factory=NavierStokes,
            params=NAVIER_STOKES_PARAMS,
            doc="Incompressible Navier–Stokes, ALE on the reference channel, skew-symmetric advection, SUPG-stabilized "
                "with grad-div, static-pressure ends with a backflow term.",
        )
    ]
