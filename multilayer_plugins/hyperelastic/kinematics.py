"""The deformation gradient of a band at its quadrature points, and the groups its dilatation is averaged over.

Total Lagrangian: every quantity is on the reference band.  The band's mesh is its reference configuration in r
and its reference stretched by λ_z (``axial_stretch``) in z, Z = z/λ_z: an artery held at λ_z times its
unloaded length, the mesh being as long as the fluid's domain.  With d = (d_z, d_r) the displacement from the
mesh, x = (z + d_z, r + d_r), so

    F = [[λ_z (1 + ∂_z d_z), ∂_r d_z, 0], [λ_z ∂_z d_r, 1 + ∂_r d_r, 0], [0, 0, 1 + d_r/r]]

in a tube (radial power k = 1; the hoop stretch 1 + d_r/r), and F_θΘ = 1 in a planar channel (plane strain,
the out-of-plane direction standing for θ).  A reference volume is the mesh's over λ_z.  F is affine in d:
H = F − I = H₀ + B d, with B (5 entries of F × local DOFs × elements × points) built once per band (the laws
take H, not F, to keep their small strains to round-off).

The volumetric energy is taken at the dilatation averaged over groups of quadrature points (mean dilatation,
theory §1): each element of a P2 band (P2 displacement, P0 dilatation: stable, no volumetric locking), each
vertex's patch of a P1 band (the elements around the vertex, a third of each one's volume; P1 with one
dilatation per element locks).  ``S`` (groups × points) holds the weights: J̄ = S J / S 1.
"""

from __future__ import annotations

import attrs
import numpy as np
import scipy.sparse as sp


@attrs.frozen(eq=False)
class BandKinematics:
    """H = F − I = H₀ + B d at every quadrature point of a band, its weights, and the assembly of element arrays."""

    B: np.ndarray  #: (5, local DOFs, elements, points): ∂F/∂d
    H0: np.ndarray  #: (5,): F − I at d = 0
    weights: np.ndarray  #: (elements, points): the reference volume of each point (the measure's, over λ_z)
    dofs: np.ndarray  #: (local DOFs, elements): the global DOF of each local one
    ndofs: int  #: the global numbering's size
    groups: sp.csr_matrix  #: S (groups × elements·points): the weights of each point in each group's dilatation

    @classmethod
    def build(cls, basis, radial_power: int, axial_stretch: float, order: int) -> BandKinematics:
        """The kinematics of a band on the vector basis ``basis`` (its ``dx`` carrying the measure).

        Raises
        ------
        ValueError
            For a geometry of radial power other than 0 or 1 (the band has one hoop direction at most).
        """
        if radial_power not in (0, 1):
            raise ValueError(f"a hyperelastic band takes a planar (k = 0) or axisymmetric (k = 1) geometry, got a "
                             f"radial power {radial_power}")
        lz = float(axial_stretch)
        nloc = len(basis.basis)
        E, Q = basis.dx.shape
        B = np.zeros((5, nloc, E, Q))
        r = basis.global_coordinates().value[1]
        for a, (phi,) in enumerate(basis.basis):
            grad = phi.grad  # (component, derivative, E, Q): ∂u_i/∂x_j with x = (z, r), u = (d_z, d_r)
            B[0, a] = lz * grad[0, 0]
            B[1, a] = grad[0, 1]
            B[2, a] = lz * grad[1, 0]
            B[3, a] = grad[1, 1]
            if radial_power:
                B[4, a] = phi[1] / r
        weights = np.asarray(basis.dx) / lz
        groups = _element_groups(weights) if order >= 2 else _vertex_groups(weights, basis.mesh.t[:, basis.tind])
        return cls(B, np.array([lz - 1.0, 0.0, 0.0, 0.0, 0.0]), weights, np.asarray(basis.element_dofs),
                   int(basis.N), groups)

    def gradient(self, d: np.ndarray) -> np.ndarray:
        """H = F − I (5, elements, points) at the displacement ``d`` (global numbering)."""
        return self.H0[:, None, None] + np.einsum("iaeq,ae->ieq", self.B, d[self.dofs])

    def vector(self, P: np.ndarray, size: bool = False) -> np.ndarray:
        """Σ_q P : ∂F/∂d assembled: the global vector of the weighted first derivatives ``P`` (5, E, Q); with
        ``size`` the elements' vectors' magnitudes summed instead (what the sum's round-off is relative to)."""
        local = np.einsum("ieq,iaeq->ae", P, self.B)
        local = np.abs(local) if size else local
        return np.bincount(self.dofs.ravel(), weights=local.ravel(), minlength=self.ndofs)

    def matrix(self, A: np.ndarray) -> sp.csr_matrix:
        """Σ_q ∂F/∂dᵀ A ∂F/∂d assembled: the global matrix of the weighted second derivatives ``A`` (5, 5, E, Q)."""
        local = np.einsum("iaeq,ijeq,jbeq->abe", self.B, A, self.B)
        rows = np.broadcast_to(self.dofs[:, None, :], local.shape)
        cols = np.broadcast_to(self.dofs[None, :, :], local.shape)
        return sp.csr_matrix((local.ravel(), (rows.ravel(), cols.ravel())), shape=(self.ndofs, self.ndofs))

    def rows(self, dJ: np.ndarray) -> sp.csr_matrix:
        """The derivative of the pointwise J in d, one row per quadrature point (elements·points × DOFs), from
        ``dJ`` = ∂J/∂F (5, E, Q)."""
        local = np.einsum("ieq,iaeq->eqa", dJ, self.B)
        E, Q, nloc = local.shape
        rows = np.broadcast_to(np.arange(E * Q).reshape(E, Q, 1), local.shape)
        cols = np.broadcast_to(self.dofs.T[:, None, :], local.shape)
        return sp.csr_matrix((local.ravel(), (rows.ravel(), cols.ravel())), shape=(E * Q, self.ndofs))


def _element_groups(weights: np.ndarray) -> sp.csr_matrix:
    """One group per element, each point weighted by its volume."""
    E, Q = weights.shape
    return sp.csr_matrix((weights.ravel(), (np.repeat(np.arange(E), Q), np.arange(E * Q))), shape=(E, E * Q))


def _vertex_groups(weights: np.ndarray, triangles: np.ndarray) -> sp.csr_matrix:
    """One group per vertex of the band: a third of every point of each element around it."""
    E, Q = weights.shape
    vertices, owner = np.unique(triangles, return_inverse=True)
    owner = owner.reshape(triangles.shape)  # (3, E): the group of each element's vertices
    rows = np.repeat(owner[:, :, None], Q, axis=2)
    cols = np.broadcast_to(np.arange(E * Q).reshape(1, E, Q), rows.shape)
    data = np.broadcast_to(weights[None] / 3.0, rows.shape)
    return sp.csr_matrix((data.ravel(), (rows.ravel(), cols.ravel())), shape=(len(vertices), E * Q))
