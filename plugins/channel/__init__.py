"""The fluid sub-problem of the kinematically coupled scheme (SCHEME §3, step A2).

Navier–Stokes (or Stokes) in the compliant channel, assembled on the fixed
reference channel with the coefficient fields of the explicit ALE map.

==================  ====================================================
module              what it holds
==================  ====================================================
``channel``         reference mesh, P2/P1 or P1b/P1 spaces, DOF sets
``ale``             J, ∇^η, w at the quadrature points
``forms``           the A2 terms as scikit-fem forms
``batched``         fast assembly of those forms through their kernels
``pattern``         the fixed sparsity pattern
``step``            one A2 step: :class:`FluidStep`
``ledger``          the A2 energy identity
``probes``          point values, flow rate, snapshots
``model``           :class:`NavierStokes`, :class:`Stokes` (plugins' factories)
==================  ====================================================
"""

from multilayer_plugins.channel.model import PARAMS, ChannelFluid, NavierStokes, Stokes, wall_motion
from multilayer_plugins.channel.step import FluidState, FluidStep, StepResult

__all__ = [
    "PARAMS",
    "ChannelFluid",
    "FluidState",
    "FluidStep",
    "NavierStokes",
    "StepResult",
    "Stokes",
    "wall_motion",
]
