"""The wall shear stress: the fluid's tangential pull on the lumen Γ, from the velocity's gradient there.

On the deformed wall Γ = {(ẑ + D_z, R + η(ẑ))} (the image of r̂ = R under the
ALE map of :mod:`multilayer_plugins.channel.ale`), with t its unit tangent
pointing downstream and n the fluid's outward unit normal,

    τ_w = −t · 2μ D(u) n,   D(u) = ½(∇u + ∇uᵀ),

the tangential component of the traction the fluid exerts on the wall (the
pressure's −p n has none): positive where the flow near the wall runs
towards z = L (Poiseuille: τ_w = −μ ∂_r u_z(R) > 0).  The hoop strain u_r/r
of a tube has no (t, n) component, so the formula is the same in every
geometry.

On the reference channel the physical gradient is ∇u = ∇̂u F⁻¹, F the map's
deformation gradient at the wall: F = [[1, 0], [η', (R + η)/R]] under the
radial map, [[1 + ∂_ẑD_z, ∂_r̂D_z], [η', (R + η)/R]] under an axial one; the
tangent is F e_ẑ, normalized, and n = (−t_r, t_z).  ∇̂u is the element's own
gradient in the cell under each wall facet, taken at the facet's points that
are line DOFs (its ends, and its midpoint under P2); a vertex shared by two
facets takes the mean of their two one-sided values.  A field the element
holds exactly (a parabola under P2: Poiseuille) has its exact τ_w, to round-off.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import skfem

from multilayer.geometry.mesh import match_by_z
from multilayer_plugins.channel.channel import Channel, line_sampling
from multilayer_plugins.channel.extension import AxialExtension

#: the points of a wall facet (its reference coordinate in [0, 1]) that are line DOFs, by element order
FACET_POINTS = {1: (0.0, 1.0), 2: (0.0, 0.5, 1.0)}


def _gradient_rows(basis: skfem.FacetBasis, components: int) -> list[list[sp.csr_matrix]]:
    """Matrices DOFs → ∂_ĵ u_i at the facet points (facets × points, flattened), [i][j]; i only for a vector."""
    nfacets, npoints = np.asarray(basis.global_coordinates()).shape[1:]
    rows = np.tile(np.arange(nfacets * npoints), basis.Nbfun)
    cols = np.concatenate([np.repeat(basis.element_dofs[k], npoints) for k in range(basis.Nbfun)])
    shape = (nfacets * npoints, basis.N)
    out = []
    for i in range(components):
        out.append([])
        for j in range(2):
            grads = [np.asarray(basis.basis[k][0].grad[(i, j) if components > 1 else (j,)]).ravel()
                     for k in range(basis.Nbfun)]
            out[i].append(sp.csr_matrix((np.concatenate(grads), (rows, cols)), shape=shape))
    return out


class WallShear:
    """τ_w at the interface line's DOFs as a function of (u, η) (and the lumen's d_z), its sampling built once.

    >>> from multilayer_plugins.planar import Planar
    >>> ch = Channel.build(Planar(), 2.0, 0.5, nz=4, nr=2, order=2)
    >>> u = ch.interpolate(lambda z, r: (3.0 * (0.25 - r ** 2), 0.0 * r))  # u_z = G(R² − r²)/(2μ), G/(2μ) = 3
    >>> tau = WallShear(ch, viscosity=0.5)(u, np.zeros(ch.line.ndofs))
    >>> bool(np.allclose(tau, 0.5 * 3.0 * 2 * 0.5, rtol=1e-13))  # −μ ∂_r u_z(R) = μ · 6R
    True
    """

    def __init__(self, channel: Channel, viscosity: float):
        self.channel, self.viscosity = channel, viscosity
        mesh, line, R = channel.mesh, channel.line, channel.radius
        tol = 1e-9 * max(channel.length, R)
        facets = mesh.facets_satisfying(lambda x: np.abs(x[1] - R) < tol, boundaries_only=True)
        points = np.array([FACET_POINTS[channel.order]])
        self._quadrature = (points, np.ones(points.shape[1]))
        self._facets = facets
        basis = skfem.FacetBasis(mesh, channel.velocity.elem, facets=facets, quadrature=self._quadrature)
        self._grad = _gradient_rows(basis, 2)
        z = np.asarray(basis.global_coordinates())[0]  # (facets, points)
        # η and η' from the line cell under each facet: the one-sided values the facet's gradient goes with
        segments = line.basis.mesh.p[0, line.basis.mesh.t]
        by_z = np.argsort(segments.min(axis=0))
        starts = segments.min(axis=0)[by_z]
        cell = by_z[np.clip(np.searchsorted(starts, z.mean(axis=1), side="right") - 1, 0, len(starts) - 1)]
        self._eta, self._eta_z = line_sampling(line, z.ravel(), np.repeat(cell, z.shape[1]))
        # each point is a line DOF; a DOF's value is the mean over the facets it is a point of
        dof = match_by_z(z.ravel(), line.z, channel.length)
        if np.any(np.abs(line.z[dof] - z.ravel()) > tol):
            raise ValueError("the wall facets' points are not the interface line's DOFs")
        count = np.bincount(dof, minlength=line.ndofs)
        if np.any(count == 0):
            raise ValueError("an interface line DOF lies on no wall facet")
        self._mean = sp.csr_matrix((1.0 / count[dof], (dof, np.arange(dof.size))), shape=(line.ndofs, dof.size))
        self._axial: tuple[AxialExtension, list] | None = None

    def _axial_rows(self, extension: AxialExtension) -> list[list[sp.csr_matrix]]:
        """∂_ẑD_z and ∂_r̂D_z at the facet points from D_z's DOFs (built at the first axially moved domain)."""
        if self._axial is None or self._axial[0] is not extension:
            basis = skfem.FacetBasis(self.channel.mesh, extension.basis.elem, facets=self._facets,
                                     quadrature=self._quadrature)
            self._axial = (extension, _gradient_rows(basis, 1)[0])
        return self._axial[1]

    def __call__(self, u: np.ndarray, eta: np.ndarray,
                 axial: tuple[AxialExtension, np.ndarray] | None = None) -> np.ndarray:
        """τ_w (dyn/cm²) at the line DOFs for the velocity DOFs ``u`` on the domain of ``eta``; ``axial`` = (the
        extension, the lumen's d_z) when the domain moves axially too."""
        R = self.channel.radius
        g = [[M @ u for M in row] for row in self._grad]  # ∂_ĵ u_i on the reference channel
        F10, F11 = self._eta_z @ eta, 1.0 + (self._eta @ eta) / R
        F00, F01 = np.ones_like(F10), np.zeros_like(F10)
        if axial is not None:
            extension, d_z = axial
            D = extension.extend(d_z)
            dz, dr = (M @ D for M in self._axial_rows(extension))
            F00, F01 = F00 + dz, dr
        det = F00 * F11 - F01 * F10
        inverse = ((F11 / det, -F01 / det), (-F10 / det, F00 / det))  # F⁻¹[k][j]
        grad = [[g[i][0] * inverse[0][j] + g[i][1] * inverse[1][j] for j in range(2)] for i in range(2)]
        length = np.hypot(F00, F10)
        t = (F00 / length, F10 / length)
        n = (-t[1], t[0])
        shear = sum((t[i] * n[j] + n[i] * t[j]) * grad[i][j] for i in range(2) for j in range(2))
        return self._mean @ (-self.viscosity * shear)
