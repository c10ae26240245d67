"""The explicit ALE map of theory §2 as coefficient fields on the reference mesh.

A_η(ẑ, r̂) = (ẑ, (R + η(ẑ)) r̂ / R) maps Ω̂ = (0, L) × (0, R) onto the fluid
domain.  On Ω̂ the physical derivatives are

    ∂_z = ∂_ẑ + g_z ∂_r̂,   g_z = −r̂ η_z / (R + η)
    ∂_r =        g_r ∂_r̂,   g_r = R / (R + η)

the Jacobian is J = (R + η)/R and the domain velocity w = v r̂/R e_r, whose
only trace in the A2 forms is ∂_t J = v/R (the moving-domain term).  All of
them are evaluated at the quadrature points of the reference mesh, from
line vectors η and v, by two sparse products fixed at setup.
"""

from __future__ import annotations

import attrs
import numpy as np

from multilayer_plugins.channel.channel import Channel


@attrs.frozen(eq=False)
class ALEFields:
    """J, g_z, g_r, ∂_t J and the radial domain velocity w_r at the quadrature points.

    Every array has the shape (elements, quadrature points) of the channel's
    velocity basis, so it can be handed to a scikit-fem form as it is.

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
    J_in: float  #: J at z = 0: stretch of the inlet's measure
    J_out: float  #: J at z = L

    @classmethod
    def at(cls, channel: Channel, eta: np.ndarray, v: np.ndarray) -> ALEFields:
        """Fields of the domain of ``eta`` moving with wall velocity ``v`` (line vectors)."""
        R = channel.radius
        shape = channel.quad_shape
        eta_q = (channel.eta_at_quad @ eta).reshape(shape)
        eta_zq = (channel.eta_z_at_quad @ eta).reshape(shape)
        v_q = (channel.eta_at_quad @ v).reshape(shape)
        stretched = R + eta_q
        if np.min(stretched) <= 0.0:
            raise ValueError(f"the wall displacement closes the channel: min(R + η) = {np.min(stretched):.3g} cm")
        rhat = channel.rhat
        return cls(
            J=stretched / R,
            gz=-rhat * eta_zq / stretched,
            gr=R / stretched,
            dJdt=v_q / R,
            wr=v_q * rhat / R,
            J_in=1.0 + float(eta[channel.ends[0]]) / R,
            J_out=1.0 + float(eta[channel.ends[1]]) / R,
        )

    @classmethod
    def rigid(cls, channel: Channel) -> ALEFields:
        """The undeformed channel at rest: J = 1, ∇^η = ∇̂, w = 0."""
        zero = np.zeros(channel.line.ndofs)
        return cls.at(channel, zero, zero)

    def forms_kwargs(self) -> dict[str, np.ndarray]:
        """The fields as the ``w`` arguments of :mod:`multilayer_plugins.channel.forms`."""
        return {"J": self.J, "gz": self.gz, "gr": self.gr}
