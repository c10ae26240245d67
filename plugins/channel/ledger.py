"""Quadratures of the fluid's energy identity: kinetic energy and end fluxes.

They are evaluated with the quadrature of the assembly, independently of the
assembled matrices, so the identity of :meth:`~multilayer_plugins.channel.step.FluidStep.identity`
is a real check of the step: it closes to round-off.
"""

from __future__ import annotations

import numpy as np

from multilayer_plugins.channel import forms
from multilayer_plugins.channel.ale import ALEFields
from multilayer_plugins.channel.channel import Channel


def fluid_kinetic(channel: Channel, density: float, J: np.ndarray, u: np.ndarray) -> float:
    """½ρ_f ∫ J |u|² on the reference channel (g·cm²/s² per unit depth); J may be any weight field."""
    return density * float(forms.kinetic.assemble(channel.velocity, u=channel.velocity.interpolate(u), J=J))


def end_fluxes(channel: Channel, fields: ALEFields, u: np.ndarray) -> tuple[float, float]:
    """(Q_in, Q_out): volume flux in through z = 0 and out through z = L (cm²/s)."""
    q_in = -float(forms.normal_flux.assemble(channel.inlet, u=channel.inlet.interpolate(u), J=fields.J_in))
    q_out = float(forms.normal_flux.assemble(channel.outlet, u=channel.outlet.interpolate(u), J=fields.J_out))
    return q_in, q_out
