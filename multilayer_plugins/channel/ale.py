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

Under no-slip at a thick first layer (``lumen = "no-slip"``) the map moves
axially too: X̂ + D with D_r = r̂ η/R and D_z the harmonic extension of the
lumen's d_z (:mod:`multilayer_plugins.channel.extension`), so

    F = I + ∇̂D = [[1 + ∂_ẑD_z, ∂_r̂D_z], [r̂ η_z/R, (R + η)/R]],

∂_z = g_zz ∂_ẑ + g_z ∂_r̂, ∂_r = g_rz ∂_ẑ + g_r ∂_r̂ with (g_zz, g_z; g_rz, g_r)
the columns of F⁻¹, the volume element J = det F ((R + η)/R)ᵏ, its rate the
exact difference quotient (J^{n+1} − Jⁿ)/Δt of the step's two ends at each
quadrature point, and the domain velocity w = (Dⁿ⁺¹ − Dⁿ)/Δt in both
components (:meth:`ALEFields.moving`).  With d_z = 0 these are the radial
map's fields.
"""

from __future__ import annotations

import attrs
import numpy as np

from multilayer_plugins.channel.channel import Channel
from multilayer_plugins.channel.extension import AxialExtension


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
    #: under an axial mesh motion: the ∂_ẑ coefficients of ∂_z and ∂_r (F⁻¹'s other column) and the
    #: domain's axial velocity w_z; None under the radial map (∂_z = ∂_ẑ + g_z ∂_r̂, ∂_r = g_r ∂_r̂, w_z = 0)
    gzz: np.ndarray | None = None
    grz: np.ndarray | None = None
    wz: np.ndarray | None = None

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
    def moving(cls, channel: Channel, extension: AxialExtension, eta: np.ndarray, v: np.ndarray,
               eta_z: np.ndarray, v_z: np.ndarray, dt: float, position: float = 0.0) -> ALEFields:
        """Fields of the domain of (``eta_z``, ``eta``) moving with the lumen's velocity (``v_z``, ``v``).

        The domain sits at tⁿ + ``position``·Δt in a step of ``dt`` > 0, as in
        :meth:`at`; the step's ends are the lumen's line moved linearly by
        (v_z, v), and the rate of J is its exact difference quotient between
        them (the GCL to round-off, whatever the degree of J in time).
        """
        if not dt > 0.0:
            raise ValueError(f"an axial mesh motion needs the step's Δt > 0, got {dt!r}")
        R, shape, rhat = channel.radius, channel.quad_shape, channel.rhat
        D, W = extension.at_quad(eta_z), extension.at_quad(v_z)  # D_z and its velocity (value, ∂_ẑ, ∂_r̂)

        def moved(s: float) -> tuple:  # F of the domain moved by s·Δt from this one
            return deformation(channel, eta + s * dt * v, tuple(d + s * dt * w for d, w in zip(D, W)))

        F = deformation(channel, eta, D)
        det = determinant(F)
        if np.min(det) <= 0.0:
            raise ValueError(f"the axial mesh motion folds the fluid domain: min det F = {np.min(det):.3g}")
        before, after = volume_element(channel, moved(-position)), volume_element(channel, moved(1.0 - position))
        v_q = (channel.eta_at_quad @ v).reshape(shape)
        return cls(
            J=volume_element(channel, F),
            gz=-F[1][0] / det,
            gr=F[0][0] / det,
            dJdt=(after - before) / dt,
            wr=v_q * rhat / R,
            J_in=1.0 + float(eta[channel.ends[0]]) / R,
            J_out=1.0 + float(eta[channel.ends[1]]) / R,
            hoop=1.0 / (F[1][1] * rhat) if channel.geometry.radial_power else None,
            hoops=channel.geometry.radial_power,
            gzz=F[1][1] / det,
            grz=-F[0][1] / det,
            wz=W[0],
        )

    @classmethod
    def rigid(cls, channel: Channel) -> ALEFields:
        """The undeformed channel at rest: J = 1, ∇^η = ∇̂, w = 0."""
        zero = np.zeros(channel.line.ndofs)
        return cls.at(channel, zero, zero)

    def forms_kwargs(self) -> dict[str, np.ndarray]:
        """The fields as the ``w`` arguments of :mod:`multilayer_plugins.channel.forms` (with ``gzz``, ``grz``
        under an axial mesh motion)."""
        if self.gzz is None:
            return {"J": self.J, "gz": self.gz, "gr": self.gr}
        return {"J": self.J, "gz": self.gz, "gr": self.gr, "gzz": self.gzz, "grz": self.grz}

    def hoop_kwargs(self) -> dict[str, np.ndarray]:
        """The fields of the hoop forms (``J`` and ``hoop`` = 1/r); only where :attr:`hoop` is not None."""
        return {"J": self.J, "hoop": self.hoop}


def deformation(channel: Channel, eta: np.ndarray, D_z: tuple) -> tuple:
    """F = I + ∇̂D at the quadrature points: nested tuples [i][j] = ∂_ĵ x_i.

    ``eta`` is the lumen's η (a line vector), ``D_z`` the axial displacement's
    (value, ∂_ẑ, ∂_r̂) at the quadrature points
    (:meth:`~multilayer_plugins.channel.extension.AxialExtension.at_quad` of the lumen's d_z).
    """
    R, shape, rhat = channel.radius, channel.quad_shape, channel.rhat
    eta_q = (channel.eta_at_quad @ eta).reshape(shape)
    eta_zq = (channel.eta_z_at_quad @ eta).reshape(shape)
    if np.min(R + eta_q) <= 0.0:
        raise ValueError(f"the wall displacement closes the channel: min(R + η) = {np.min(R + eta_q):.3g} cm")
    return ((1.0 + D_z[1], D_z[2]), (rhat * eta_zq / R, (R + eta_q) / R))


def determinant(F: tuple) -> np.ndarray:
    """det F of a 2 × 2 field in nested tuples."""
    return F[0][0] * F[1][1] - F[0][1] * F[1][0]


def volume_element(channel: Channel, F: tuple) -> np.ndarray:
    """J = det F · (r/r̂)ᵏ of the map with :func:`deformation` F (r/r̂ = (R + η)/R = F_rr)."""
    return determinant(F) * F[1][1] ** channel.geometry.radial_power
