"""The axial part of the mesh motion under no-slip: the harmonic extension of the lumen's d_z.

Under ``lumen = "no-slip"`` the fluid domain follows the wall's axial motion
too: the map of Ω̂ is X̂ + D with D = (D_z, D_r), D_r = r̂ η(ẑ)/R the radial
map of :mod:`multilayer_plugins.channel.ale`, and D_z the harmonic extension
of the lumen's axial displacement into Ω̂:

    Δ̂ D_z = 0 in Ω̂,  D_z = d_z on r̂ = R,  D_z = 0 on ẑ = 0 and ẑ = L,  ∂_r̂ D_z = 0 on the axis,

in the scalar Lagrange space of the fluid's order (P2 under Taylor–Hood, P1
under MINI), whose DOFs on r̂ = R are the interface line's.  The interior
block of the Laplacian is factorized once at setup; a step samples D_z and
its two reference derivatives at the velocity basis' quadrature points by
three sparse products.  The line's end DOFs must carry d_z = 0 (the
domain's length is fixed): :meth:`AxialExtension.extend` refuses others.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import skfem
from skfem.models.poisson import laplace

from multilayer_plugins.channel.channel import Channel

SCALAR_ELEMENTS = {2: skfem.ElementTriP2, 1: skfem.ElementTriP1}


def _sampling(basis: skfem.CellBasis) -> tuple[sp.csr_matrix, sp.csr_matrix, sp.csr_matrix]:
    """Matrices scalar DOFs → value, ∂_ẑ and ∂_r̂ at the quadrature points (elements × points, flattened)."""
    nelems, nqp = np.shape(basis.basis[0][0])
    rows = np.arange(nelems * nqp).reshape(nelems, nqp)
    value, dz, dr, cols = [], [], [], []
    for i in range(basis.Nbfun):
        phi = basis.basis[i][0]
        value.append(np.asarray(phi).ravel())
        dz.append(phi.grad[0].ravel())
        dr.append(phi.grad[1].ravel())
        cols.append(np.repeat(basis.element_dofs[i], nqp))
    r = np.tile(rows.ravel(), basis.Nbfun)
    c = np.concatenate(cols)
    shape = (nelems * nqp, basis.N)
    return tuple(sp.csr_matrix((np.concatenate(x), (r, c)), shape=shape) for x in (value, dz, dr))


class AxialExtension:
    """D_z = E d_z, the harmonic extension of a line vector into the reference channel, sampled at quadrature.

    >>> from multilayer_plugins.planar import Planar
    >>> ch = Channel.build(Planar(), 2.0, 0.5, nz=4, nr=2, order=2)
    >>> ext = AxialExtension(ch)
    >>> dz = 0.01 * np.sin(np.pi * ch.line.z / 2.0)
    >>> value, d_zhat, d_rhat = ext.at_quad(dz)
    >>> value.shape == ch.quad_shape, bool(abs(ext.extend(dz)[ext.wall] - dz[ext.wall_line]).max() < 1e-15)
    (True, True)
    """

    def __init__(self, channel: Channel):
        self.channel = channel
        mesh = channel.mesh
        element = SCALAR_ELEMENTS[channel.order]()
        basis = skfem.Basis(mesh, element, quadrature=channel.velocity.quadrature)
        self.basis = basis
        A = skfem.asm(laplace, skfem.Basis(mesh, element, intorder=2 * channel.order)).tocsr()
        z, r = basis.doflocs
        tol = 1e-9 * max(channel.length, channel.radius)
        on_wall = np.abs(r - channel.radius) < tol
        on_ends = (np.abs(z) < tol) | (np.abs(z - channel.length) < tol)
        #: scalar DOFs on r̂ = R and the line DOF each one is
        self.wall = np.flatnonzero(on_wall)
        line_z = channel.line.z
        self.wall_line = np.array([int(np.argmin(np.abs(line_z - zz))) for zz in z[self.wall]])
        if np.max(np.abs(line_z[self.wall_line] - z[self.wall])) > tol:
            raise ValueError("the interface line's DOFs are not the scalar space's DOFs on r̂ = R")
        fixed = np.flatnonzero(on_wall | on_ends)
        self._ends = np.flatnonzero(on_ends)  # Γ's corners among them: D_z = 0 there
        self.interior = np.setdiff1d(np.arange(basis.N), fixed)
        self._fixed = fixed
        self._coupling = A[self.interior][:, fixed].tocsr()
        self._lu = spla.splu(A[self.interior][:, self.interior].tocsc())
        self._value, self._dz, self._dr = _sampling(basis)

    def extend(self, d_z: np.ndarray) -> np.ndarray:
        """The scalar DOFs of D_z for the line vector ``d_z`` (zero at the line's ends)."""
        ch = self.channel
        ends = np.asarray(ch.ends)
        scale = max(float(np.max(np.abs(d_z))), 1e-300)
        if np.max(np.abs(d_z[ends])) > 1e-12 * scale:
            raise ValueError("the lumen's axial displacement must vanish at z = 0 and z = L (the domain's length "
                             f"is fixed), got d_z = {d_z[ends[0]]:.3g}, {d_z[ends[1]]:.3g} cm there")
        D = np.zeros(self.basis.N)
        D[self.wall] = d_z[self.wall_line]
        D[self._ends] = 0.0
        D[self.interior] = -self._lu.solve(self._coupling @ D[self._fixed])
        return D

    def radial_slope_probes(self, x: np.ndarray) -> sp.csr_matrix:
        """The matrix of D_z's DOFs → ∂_r̂ D_z at the reference points ``x`` (2 × n), each inside a cell."""
        basis = self.basis
        cells = basis.mesh.element_finder(mapping=basis.mapping)(*x)
        local = basis.mapping.invF(x[:, :, np.newaxis], tind=cells)
        slopes = [np.asarray(basis.elem.gbasis(basis.mapping, local, k, tind=cells)[0].grad[1]).ravel()
                  for k in range(basis.Nbfun)]
        rows = np.tile(np.arange(x.shape[1]), basis.Nbfun)
        cols = basis.element_dofs[:, cells].ravel()
        return sp.csr_matrix((np.concatenate(slopes), (rows, cols)), shape=(x.shape[1], basis.N))

    def at_vertices(self, d_z: np.ndarray) -> np.ndarray:
        """D_z at the mesh vertices (in the mesh's vertex order)."""
        return self.extend(d_z)[self.basis.nodal_dofs[0]]

    def at_quad(self, d_z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(D_z, ∂_ẑ D_z, ∂_r̂ D_z) at the quadrature points, each of the channel's ``quad_shape``."""
        D = self.extend(d_z)
        shape = self.channel.quad_shape
        return tuple((M @ D).reshape(shape) for M in (self._value, self._dz, self._dr))
