"""Quadratures of the fluid's energy identity: kinetic energy, viscous dissipation, end fluxes.

The terms are evaluated at the quadrature points of the assembly, from the
reference jets of :class:`multilayer.numerics.assembly.batched.BatchedForm` (one
matrix product per field, no second pass of scikit-fem interpolation and
functional assembly), with the integrands of :mod:`multilayer_plugins.channel.forms`.
They do not use the assembled matrix: each kinetic energy is weighted by the
J of the domain it belongs to (ηⁿ, η^{n+1}), not by the step's J_m, so the
identity of :meth:`~multilayer_plugins.channel.step.FluidStep.identity` is a
real check of the step (docs/performance.md, "The ledger").
"""

from __future__ import annotations

import numpy as np
from skfem.assembly.form.form import FormExtraParams

from multilayer.numerics.assembly.batched import BatchedForm
from multilayer_plugins.channel import forms
from multilayer_plugins.channel.ale import ALEFields
from multilayer_plugins.channel.channel import Channel


def fluid_kinetic(channel: Channel, density: float, J: np.ndarray, u: np.ndarray) -> float:
    """½ρ_f ∫ J |u|² on the reference channel (g·cm²/s² per unit depth); J may be any weight field."""
    return density * float(forms.kinetic.assemble(channel.velocity, u=channel.velocity.interpolate(u), J=J))


def end_fluxes(channel: Channel, fields: ALEFields, u: np.ndarray) -> tuple[float, float]:
    """(Q_in, Q_out): volume flux in through z = 0 and out through z = L (cm²/s)."""
    J_in, J_out = channel.geometry.stretch(fields.J_in), channel.geometry.stretch(fields.J_out)
    q_in = -float(forms.normal_flux.assemble(channel.inlet, u=channel.inlet.interpolate(u), J=J_in))
    q_out = float(forms.normal_flux.assemble(channel.outlet, u=channel.outlet.interpolate(u), J=J_out))
    return q_in, q_out


class Quadrature:
    """The identity's integrals on the velocity space's quadrature, from the assembly's reference jets.

    Parameters
    ----------
    form : BatchedForm
        The velocity block's batched form (its jets and weights dx).
    density : float
        ρ_f.
    """

    def __init__(self, form: BatchedForm, density: float):
        self.form, self.density = form, density

    def values(self, u: np.ndarray) -> np.ndarray:
        """u's values (component, elements, points) at the quadrature points: what :meth:`kinetic` takes.

        They are linear in u, so a time scheme's combinations of levels may
        be formed on the values of each level, computed once.
        """
        return self.form.trial_jets(u, values_only=True)

    def kinetic(self, J: np.ndarray, v: np.ndarray) -> float:
        """½ρ_f ∫ J |u|² from u's :meth:`values` ``v``, as :func:`fluid_kinetic` (to round-off)."""
        return 0.5 * self.density * float(np.sum(self.form.dx * J * (v[0] * v[0] + v[1] * v[1])))

    def strain_squared(self, u: np.ndarray, fields: ALEFields) -> float:
        """∫ J |D^η(u)|² (the integrand :data:`forms.strain_squared`, with k times
        :data:`forms.hoop_squared` in a tube), chunk by chunk of elements.

        Per chunk, so the jets and the integrand's intermediate arrays stay
        small: on a large mesh whole-mesh arrays are fresh pages every step.
        """
        kw = fields.forms_kwargs()
        if fields.hoop is not None:
            kw["hoop"] = fields.hoop
        total = 0.0
        for cut in self.form.chunks():
            w = FormExtraParams({"u": self.form.field(u, cut),
                                 **{k: np.asarray(a)[..., cut, :] if np.ndim(a) >= 2 else a for k, a in kw.items()}})
            integrand = forms.strain_squared.form(w)
            if fields.hoop is not None:
                integrand = integrand + fields.hoops * forms.hoop_squared.form(w)
            total += float(np.sum(self.form.dx[cut] * integrand))
        return total
