"""The energy identity of step A2 (SCHEME §4), term by term.

Testing A2 with (u, v) = (u^{n+1}, v^{n+1}) and using Jⁿ + Δt v^{n+½}/R = J^{n+1}:

    ½ρ_f∫J^{n+1}|u^{n+1}|² + ½ρ_f∫Jⁿ|u^{n+1}−uⁿ|² + ½(‖v^{n+1}‖² + ‖v^{n+1}−v^{n+½}‖²)_M
        + 2μΔt ∫Jⁿ|D^η(u^{n+1})|²
    = ½ρ_f∫Jⁿ|uⁿ|² + ½‖v^{n+½}‖²_M + Δt(P_in∫_Γin u_z − P_out∫_Γout u_z) + W_wall

with ‖·‖_M the norm of the thin layer's Robin mass M = ρ₁h∫vψ.  W_wall is
the work of a wall whose motion is prescribed (a Dirichlet condition on u_r):
Δt x_D·(A x − b)_D, the discrete power of the reaction; it is zero when the
wall is rigid or coupled.  Every integral is evaluated independently of the
assembled matrices, with the same quadrature, so the residual is a real
check of the step: it closes to round-off.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from multilayer_plugins.channel import forms
from multilayer_plugins.channel.ale import ALEFields
from multilayer_plugins.channel.channel import Channel

#: Terms on the left of the identity (after the step) and on the right (before it, plus work).
AFTER = (
    "fluid.kinetic",
    "fluid.numerical_dissipation",
    "fluid.viscous_dissipation",
    "thin.kinetic",
    "thin.numerical_dissipation",
)
BEFORE = ("fluid.kinetic_before", "thin.kinetic_before", "inlet.work", "outlet.work", "wall.work")


def fluid_kinetic(channel: Channel, density: float, J: np.ndarray, u: np.ndarray) -> float:
    """½ρ_f ∫ J |u|² on the reference channel (g·cm²/s² per unit depth)."""
    return density * float(forms.kinetic.assemble(channel.velocity, u=channel.velocity.interpolate(u), J=J))


def end_fluxes(channel: Channel, fields: ALEFields, u: np.ndarray) -> tuple[float, float]:
    """(Q_in, Q_out): volume flux in through z = 0 and out through z = L (cm²/s)."""
    q_in = -float(forms.normal_flux.assemble(channel.inlet, u=channel.inlet.interpolate(u), J=fields.J_in))
    q_out = float(forms.normal_flux.assemble(channel.outlet, u=channel.outlet.interpolate(u), J=fields.J_out))
    return q_in, q_out


def a2_terms(
    channel: Channel,
    density: float,
    viscosity: float,
    dt: float,
    fields: ALEFields,
    u_old: np.ndarray,
    u: np.ndarray,
    v_half: np.ndarray,
    v: np.ndarray,
    p_in: float,
    p_out: float,
    robin_mass: sp.spmatrix | None,
    wall_work: float,
) -> dict[str, float]:
    """Every term of the A2 identity, its residual (after − before) and its scale (Σ|terms|)."""
    basis = channel.velocity
    J_new = fields.J + dt * fields.dJdt
    du = u - u_old
    strain = forms.strain_squared.assemble(basis, u=basis.interpolate(u), **fields.forms_kwargs())
    q_in, q_out = end_fluxes(channel, fields, u)
    M = robin_mass if robin_mass is not None else sp.csr_matrix((len(v), len(v)))
    dv = v - v_half
    terms = {
        "fluid.kinetic": fluid_kinetic(channel, density, J_new, u),
        "fluid.numerical_dissipation": fluid_kinetic(channel, density, fields.J, du),
        "fluid.viscous_dissipation": 2.0 * viscosity * dt * float(strain),
        "thin.kinetic": 0.5 * float(v @ (M @ v)),
        "thin.numerical_dissipation": 0.5 * float(dv @ (M @ dv)),
        "fluid.kinetic_before": fluid_kinetic(channel, density, fields.J, u_old),
        "thin.kinetic_before": 0.5 * float(v_half @ (M @ v_half)),
        "inlet.work": dt * p_in * q_in,
        "outlet.work": -dt * p_out * q_out,
        "wall.work": wall_work,
    }
    terms["a2.residual"] = sum(terms[k] for k in AFTER) - sum(terms[k] for k in BEFORE)
    terms["a2.scale"] = sum(abs(terms[k]) for k in AFTER + BEFORE)
    return terms


def ledger_groups(energy: dict[str, float]) -> tuple[dict, dict, dict]:
    """The A2 terms of a step as groups of :func:`multilayer.ledger.close`: (stored, work, dissipation)."""
    stored = {"kinetic.fluid": energy["fluid.kinetic"]}
    work = {"work.inlet": energy["inlet.work"], "work.outlet": energy["outlet.work"]}
    dissipation = {
        "dissipation.viscous.fluid": energy["fluid.viscous_dissipation"],
        "dissipation.numerical.A2": energy["fluid.numerical_dissipation"] + energy["thin.numerical_dissipation"],
    }
    return stored, work, dissipation
