"""Values of a fluid state in the physical (deformed) channel: probes and snapshots.

A physical point (z, r) of the domain of η is the reference point
(z, r̂ = R r / (R + η(z))); fields are evaluated there on the fixed mesh.
Probes of a run are built once as samplers: their reference points do not
move, only J(z) of a flow rate changes with the wall.
"""

from __future__ import annotations

import numpy as np

from multilayer_plugins.channel.channel import Channel
from multilayer_plugins.channel.extension import AxialExtension


def wall_displacement(channel: Channel, eta: np.ndarray, z: np.ndarray) -> np.ndarray:
    """η(z) for a line vector η."""
    z = np.atleast_1d(np.asarray(z, dtype=float))
    return channel.line.basis.probes(z[None, :]) @ eta


def to_reference(channel: Channel, eta: np.ndarray, z, r,
                 axial: tuple[AxialExtension, np.ndarray] | None = None) -> np.ndarray:
    """Reference points (ẑ, r̂) of physical points (z, r): a (2, n) array.

    Under an axial mesh motion (``axial`` = the extension and the lumen's d_z)
    ẑ solves ẑ + D_z(ẑ, r̂) = z by fixed-point iteration (a contraction while
    |∂_ẑD_z| < 1, which a map that does not fold has), r̂ = R r/(R + η(ẑ)).
    """
    z = np.atleast_1d(np.asarray(z, dtype=float))
    r = np.broadcast_to(np.asarray(r, dtype=float), z.shape)
    R = channel.radius
    if axial is None:
        return np.vstack([z, R * r / (R + wall_displacement(channel, eta, z))])
    extension, d_z = axial
    D = extension.extend(d_z)
    zhat = z.copy()
    for _ in range(100):
        x = np.vstack([zhat, R * r / (R + wall_displacement(channel, eta, zhat))])
        moved = np.clip(z - extension.basis.probes(x) @ D, 0.0, channel.length)
        if np.max(np.abs(moved - zhat)) <= 4 * np.finfo(float).eps * channel.length:
            break
        zhat = moved
    return np.vstack([moved, R * r / (R + wall_displacement(channel, eta, moved))])


def velocity(channel: Channel, u: np.ndarray, eta: np.ndarray, z, r,
             axial: tuple[AxialExtension, np.ndarray] | None = None) -> np.ndarray:
    """(u_z, u_r) at physical points: a (2, n) array (cm/s); ``axial`` as in :func:`to_reference`."""
    x = to_reference(channel, eta, z, r, axial)
    return (channel.velocity.probes(x) @ u).reshape(2, -1)


def pressure(channel: Channel, p: np.ndarray, eta: np.ndarray, z, r,
             axial: tuple[AxialExtension, np.ndarray] | None = None) -> np.ndarray:
    """p at physical points (dyn/cm²); ``axial`` as in :func:`to_reference`."""
    return channel.pressure.probes(to_reference(channel, eta, z, r, axial)) @ p


def section_nodes(channel: Channel, z: float) -> np.ndarray:
    """r̂ where the vertical line ẑ = z crosses mesh edges (0 and R included), sorted."""
    mesh = channel.mesh
    ends = mesh.p[:, mesh.facets]  # (2 coords, 2 ends, facets)
    z0, z1 = ends[0]
    r0, r1 = ends[1]
    crossing = (np.minimum(z0, z1) <= z) & (z <= np.maximum(z0, z1)) & (z0 != z1)
    s = (z - z0[crossing]) / (z1[crossing] - z0[crossing])
    r = r0[crossing] + s * (r1[crossing] - r0[crossing])
    return np.unique(np.concatenate([[0.0, channel.radius], r]))


def flow_rate_sampler(channel: Channel, z: float, extension: AxialExtension | None = None):
    """Q(z) as a function of (u, η) (and the lumen's d_z with an ``extension``), its sampling built once.

    Q(z) = ∫₀^{R+η(z)} u_z weight(r) dr = J(z)^{1+k} ∫₀^R u_z(z, r̂) weight(r̂) dr̂ in the
    geometry's measure weight(r) = c rᵏ (cm²/s per unit depth in the planar
    channel), exact for the element when the weight is a constant:
    Gauss–Legendre with three points between consecutive crossings of mesh
    edges integrates P2 and P1b velocities exactly.  Neither the points nor
    the weights depend on η, so only J(z) changes with the wall.

    Under an axial mesh motion the section ẑ = z is the curve moved by D, its
    normal times length cof(F) e_ẑ dr̂ = (J, −∂_r̂D_z) dr̂: the sampler called
    with d_z adds −Jᵏ ∫ u_r ∂_r̂D_z weight(r̂) dr̂ (degree ≤ 4 along the
    section: exact with the same points).
    """
    nodes = section_nodes(channel, z)
    g, wg = np.polynomial.legendre.leggauss(3)
    a, b = nodes[:-1, None], nodes[1:, None]
    rhat = (0.5 * (a + b) + 0.5 * (b - a) * g).ravel()
    weights = (0.5 * (b - a) * wg).ravel() * channel.geometry.weight(rhat)
    x = np.vstack([np.full_like(rhat, z), rhat])
    row = weights @ channel.velocity.probes(x).tocsr()[: len(rhat)]  # the u_z rows
    eta_row = channel.line.basis.probes(np.array([[z]])).tocsr()
    R = channel.radius
    tilt = None
    if extension is not None:  # the u_r rows at the points, and ∂_r̂D_z there
        u_r = channel.velocity.probes(x).tocsr()[len(rhat):]
        tilt = (u_r, extension.radial_slope_probes(x), weights)

    def sample(u: np.ndarray, eta: np.ndarray, d_z: np.ndarray | None = None) -> float:
        J = 1.0 + float((eta_row @ eta)[0]) / R
        q = channel.geometry.stretch(J) * float(row @ u)
        if d_z is None:
            return q
        u_r, slope, w = tilt
        return q - J ** channel.geometry.radial_power * float(w @ ((u_r @ u) * (slope @ extension.extend(d_z))))

    return sample


def flow_rate(channel: Channel, u: np.ndarray, eta: np.ndarray, z: float,
              axial: tuple[AxialExtension, np.ndarray] | None = None) -> float:
    """Q(z) (cm²/s); see :func:`flow_rate_sampler` (``axial``: the extension and the lumen's d_z)."""
    if axial is None:
        return flow_rate_sampler(channel, z)(u, eta)
    return flow_rate_sampler(channel, z, axial[0])(u, eta, axial[1])


def reference_point_sampler(channel: Channel, quantity: str, z: float, rhat: float):
    """u_z, u_r or p at the reference point (z, r̂), as a function of (u, p).

    The point follows the ALE map: it sits at r = r̂ (R + η(z))/R in the
    physical channel, so it never leaves the fluid however the wall moves.
    """
    x = np.array([[z], [rhat]])
    if quantity == "p":
        row = channel.pressure.probes(x).tocsr()
        return lambda u, p: float((row @ p)[0])
    row = channel.velocity.probes(x).tocsr()[{"u_z": 0, "u_r": 1}[quantity]]
    return lambda u, p: float((row @ u)[0])


def snapshot(channel: Channel, u: np.ndarray, p: np.ndarray, eta: np.ndarray,
             axial: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """(points, triangles, point_data) of the mesh vertices in the physical geometry.

    ``points`` is (n, 2) in (z, r); ``point_data`` holds ``velocity`` (n, 2),
    ``pressure`` (n,) and ``displacement`` (n, 2), the ALE displacement
    (D_z, η r̂/R) that moves a vertex of Ω̂ to its place: D_z = ``axial`` at the
    vertices under an axial mesh motion, 0 otherwise.
    """
    mesh = channel.mesh
    zhat, rhat = mesh.p
    eta_v = wall_displacement(channel, eta, zhat)
    displacement = np.vstack([np.zeros_like(zhat) if axial is None else axial, eta_v * rhat / channel.radius])
    vertex_u = channel.velocity.nodal_dofs  # (2 components, vertices)
    vel = u[vertex_u]
    pres = p[channel.pressure.nodal_dofs[0]]
    points = (mesh.p + displacement).T
    data = {"velocity": vel.T.copy(), "pressure": pres.copy(), "displacement": displacement.T.copy()}
    return points, mesh.t.T.copy(), data


def l2_error(channel: Channel, u: np.ndarray, eta: np.ndarray, exact) -> float:
    """‖u_h − u‖ in L²(Ω(η)) for ``exact(z, r) -> (u_z, u_r)`` given on the physical domain.

    Evaluated with the quadrature of the assembly, J^{1+k} dx̂ being the physical measure.
    """
    basis = channel.velocity
    R = channel.radius
    eta_q = (channel.eta_at_quad @ eta).reshape(channel.quad_shape)
    J = (R + eta_q) / R
    zq, rq = np.asarray(basis.global_coordinates())
    ez, er = exact(zq, J * rq)
    uh = np.asarray(basis.interpolate(u))
    integrand = channel.geometry.stretch(J) * ((uh[0] - ez) ** 2 + (uh[1] - er) ** 2)
    return float(np.sqrt(np.sum(integrand * basis.dx)))
