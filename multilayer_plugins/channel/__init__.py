"""The channel fluid: Navier–Stokes (or Stokes) in the compliant channel, a plugin like any other.

Assembled on the fixed reference channel with the coefficient fields of the
explicit ALE map (theory §2–§6), for any time scheme of
:mod:`multilayer.numerics.timescheme`; the assembly machinery it uses
(:mod:`multilayer.assembly`) is the core's.

==================  ====================================================
module              what it holds
==================  ====================================================
``channel``         reference mesh, P2/P1 or P1b/P1 spaces, DOF sets
``ale``             J, ∇^η, w at the quadrature points
``stabilization``   SUPG and grad-div of the Navier–Stokes step
``forms``           the A2 terms as scikit-fem forms
``ends``            the open ends' loads, resistances and multipliers
``end_convection``  static-pressure ends: the convective and backflow term
``step``            one step: system, solve, energy identity (:class:`FluidStep`)
``ledger``          quadratures of the energy identity
``probes``          point values, flow rate, snapshots
``wall_shear``      the wall shear stress τ_w on the lumen
``model``           :class:`NavierStokes`, :class:`Stokes` (plugins' factories)
==================  ====================================================
"""

from multilayer_plugins.channel.model import (
    NAVIER_STOKES_PARAMS,
    PARAMS,
    ChannelFluid,
    NavierStokes,
    Stokes,
    wall_motion,
)
from multilayer_plugins.channel.step import FluidState, FluidStep, FluidSystem, Solution

__all__ = [
    "NAVIER_STOKES_PARAMS",
    "PARAMS",
    "ChannelFluid",
    "FluidState",
    "FluidStep",
    "NavierStokes",
    "FluidSystem",
    "Solution",
    "Stokes",
    "wall_motion",
]
