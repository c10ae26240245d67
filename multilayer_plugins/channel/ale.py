"""The explicit ALE map of theory §2 as coefficient fields on the reference mesh.

A_η(ẑ, r̂) = (ẑ, (R + η(ẑ)) r̂ / R) maps Ω̂ = (0, L) × (0, R) onto the fluid
domain.  On Ω̂ the physical derivatives are

    ∂_z = ∂_ẑ + g_z ∂_r̂,   g_z = −r̂ η_z / (R + η)
    ∂_r =        g_r ∂_r̂,   g_r = R / (R + η)

the stretch is J = (R + η)/R and the domain velocity w = v r̂/R e_r, whose
only trace in the A2 forms is the growth of the volume element (the
moving-domain term).  In a geometry of measure c rᵏ dz dr the volume element
grows by J^{1+k} (J in the planar channel, J² in a tube), and its rate over
a step is the exact difference quotient of J^{1+k} between the step's ends
(:meth:`multilayer.geometry.contract.Geometry.stretch_rate`): v/R in the
planar channel, (v/R)(Jⁿ + J^{n+1}) in a tube.  A tube's forms also take
1/r = 1/(J r̂), the hoop factor.  All of them are evaluated at the quadrature
points of the reference mesh, from line vectors η and v, by two sparse
products fixed at setup.
"""

from __future__ import annotations

import attrs
import numpy as np

from multilayer_plugins.channel.channel import Channel


@attrs.frozen(eq=False)
class ALEFields:
    """J^{1+k}, g_z, g_r, its rate, the radial domain velocity w_r and 1/r at the quadrature points.

    Every array has the shape (elements, quadrature points) of the channel's
    velocity basis, so it can be handed to a scikit-fem form as it is.
    ``J`` is the volume element's factor J^{1+k} of the geometry (the map's
    stretch (R + η)/R in the planar channel), ``dJdt`` its rate over the step.

    >>> from multilayer_plugins.planar import Planar
    >>> ch = Channel.build(Planar(), 1.0, 0.5, 2, 2, order=1)
    >>> f = ALEFields.at(ch, 0.1 * np.ones(ch.line.ndofs), np.zeros(ch.line.ndofs))
    >>> float(f.J.min()), float(f.J.max()), float(abs(f.gz).max())
    (1.2, 1.2, 0.0)
    """

    J: np.ndarray
    gz: np.ndarray
    gr: np.ndarray
    dJdt: np.ndarray
    wr: np.ndarray
    J_in: float  #: the map's stretch (R + η)/R at z = 0 (the end's measure grows by its J^{1+k})
    J_out: float  #: at z = L
    #: 1/r at the quadrature points (r = J r̂ in the domain), None in a geometry without hoop terms (k = 0)
    hoop: np.ndarray | None = None
    #: k: how many hoop directions the measure c rᵏ has (1 in a tube), each with its u_r/r
    hoops: int = 0

    @classmethod
    def at(cls, channel: Channel, eta: np.ndarray, v: np.ndarray, dt: float = 0.0,
           position: float = 0.0) -> ALEFields:
        """Fields of the domain of ``eta`` moving with wall velocity ``v`` (line vectors).

        The domain sits at tⁿ + ``position``·Δt in a step of ``dt`` (the time
        scheme's :attr:`~multilayer.numerics.timescheme.TimeScheme.geometry_position`):
        the volume element's rate is its change from the step's start to its
        end, where the wall moved by v.  Only a geometry with k > 0 uses it.
        """
        R = channel.radius
        geometry = channel.geometry
        shape = channel.quad_shape
        eta_q = (channel.eta_at_quad @ eta).reshape(shape)
        eta_zq = (channel.eta_z_at_quad @ eta).reshape(shape)
        v_q = (channel.eta_at_quad @ v).reshape(shape)
        stretched = R + eta_q
        if np.min(stretched) <= 0.0:
            raise ValueError(f"the wall displacement closes the channel: min(R + η) = {np.min(stretched):.3g} cm")
        rhat = channel.rhat
        J, rate, hoop = stretched / R, v_q / R, None
        if geometry.radial_power:
            J, rate = geometry.stretch(J), geometry.stretch_rate(J - position * dt * rate,
                                                                J + (1.0 - position) * dt * rate, rate)
            hoop = 1.0 / (stretched / R * rhat)
        return cls(
            J=J,
            gz=-rhat * eta_zq / stretched,
            gr=R / stretched,
            dJdt=rate,
            wr=v_q * rhat / R,
            J_in=1.0 + float(eta[channel.ends[0]]) / R,
            J_out=1.0 + float(eta[channel.ends[1]]) / R,
            hoop=hoop,
            hoops=geometry.radial_power,
        )

    @classmethod
    def rigid(cls, channel: Channel) -> ALEFields:
        """The undeformed channel at rest: J = 1, ∇^η = ∇̂, w = 0."""
        zero = np.zeros(channel.line.ndofs)
        return cls.at(channel, zero, zero)

    def forms_kwargs(self) -> dict[str, np.ndarray]:
        """The fields as the ``w`` arguments of :mod:`multilayer_plugins.channel.forms`."""
        return {"J": self.J, "gz": self.gz, "gr": self.gr}

    def hoop_kwargs(self) -> dict[str, np.ndarray]:
        """The fields of the hoop forms (``J`` and ``hoop`` = 1/r); only where :attr:`hoop` is not None."""
        return {"J": self.J, "hoop": self.hoop}
