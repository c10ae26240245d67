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
    """H = F − I = H₀ + B d at every quadrature point of a band, its weights, and the assembly of element arrays.

    B is held as (elements, points, 5, local DOFs), so that every contraction with it is a batched matrix
    product; the global matrix's sparsity and where each element entry adds into it are found once.
    """

    B: np.ndarray  #: (elements, points, 5, local DOFs): ∂F/∂d
    H0: np.ndarray  #: (5,), or (5, elements, points) on a stress-free reference off the mesh: F − I at d = 0
    weights: np.ndarray  #: (elements, points): the reference volume of each point (the measure's, over λ_z)
    dofs: np.ndarray  #: (local DOFs, elements): the global DOF of each local one
    ndofs: int  #: the global numbering's size
    groups: sp.csr_matrix  #: S (groups × elements·points): the weights of each point in each group's dilatation
    per_element: bool  #: the groups are the elements (group e is element e)
    pattern: tuple = attrs.field(init=False)  #: (indices, indptr, where each element entry adds) of the matrix
    groups_t: sp.csr_matrix = attrs.field(init=False)  #: Sᵀ (points × groups), formed once: m = Sᵀ U'(J̄)
    volumes: np.ndarray = attrs.field(init=False)  #: V = S 1, the groups' volumes

    def __attrs_post_init__(self):
        object.__setattr__(self, "groups_t", self.groups.T.tocsr())
        object.__setattr__(self, "volumes", np.asarray(self.groups.sum(axis=1)).ravel())
        nloc, E = self.dofs.shape
        rows = np.broadcast_to(self.dofs.T[:, :, None], (E, nloc, nloc)).ravel()
        cols = np.broadcast_to(self.dofs.T[:, None, :], (E, nloc, nloc)).ravel()
        entries, where = np.unique(rows * np.int64(self.ndofs) + cols, return_inverse=True)
        indptr = np.searchsorted(entries // self.ndofs, np.arange(self.ndofs + 1))
        object.__setattr__(self, "pattern", ((entries % self.ndofs).astype(np.int32), indptr, where.ravel()))

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
        r = basis.global_coordinates()[1]
        for a, (phi,) in enumerate(basis.basis):
            grad = phi.grad  # (component, derivative, E, Q): ∂u_i/∂x_j with x = (z, r), u = (d_z, d_r)
            B[0, a] = lz * grad[0, 0]
            B[1, a] = grad[0, 1]
            B[2, a] = lz * grad[1, 0]
            B[3, a] = grad[1, 1]
            if radial_power:
                B[4, a] = phi[1] / r
        weights = np.asarray(basis.dx) / lz
        per_element = order >= 2
        groups = _element_groups(weights) if per_element else _vertex_groups(weights, basis.mesh.t[:, basis.tind])
        return cls(np.ascontiguousarray(B.transpose(2, 3, 0, 1)), np.array([lz - 1.0, 0.0, 0.0, 0.0, 0.0]),
                   weights, np.asarray(basis.element_dofs), int(basis.N), groups, per_element)

    def gradient(self, d: np.ndarray) -> np.ndarray:
        """H = F − I (5, elements, points) at the displacement ``d`` (global numbering)."""
        H = (self.B @ d[self.dofs].T[:, None, :, None])[..., 0]  # (E, Q, 5)
        H0 = self.H0 if self.H0.ndim == 3 else self.H0[:, None, None]
        return H0 + H.transpose(2, 0, 1)

    def referenced(self, D: np.ndarray) -> BandKinematics:
        """The kinematics of the band whose reference is the mesh moved by ``D`` (global numbering), stretched
        back by λ_z (docs/theory-wall.md, "A prestressed wall"): F = (I + ∇d)(I + ∇D)⁻¹ Λ, with Λ the axial stretch, so
        that at d = D the band is its reference stretched by λ_z alone; the reference volumes are the mesh's over
        det((I + ∇D)⁻¹ Λ).

        F is still affine in d, F = F_λ(d) M with F_λ this kinematics' F and M = Λ⁻¹(I + ∇D)⁻¹Λ at each point
        (its hoop entry r/(r + D_r)): B and H₀ are composed with M on the right, the weights and the groups'
        weights divided by det M.  D = 0 gives these kinematics back.
        """
        a = (self.B @ D[self.dofs].T[:, None, :, None])[..., 0].transpose(2, 0, 1)  # (∇D)Λ, D_r/r: (5, E, Q)
        if self.H0.ndim != 1:
            raise ValueError("the kinematics are referenced already: build them from the mesh's")
        lz = 1.0 + self.H0[0]
        n00, n01, n10, n11 = 1.0 + a[0] / lz, a[1] / lz, a[2], 1.0 + a[3]  # N = I + Λ⁻¹(∇D)Λ
        det = n00 * n11 - n01 * n10
        m = np.stack([n11 / det, -n01 / det, -n10 / det, n00 / det, 1.0 / (1.0 + a[4])])  # M = N⁻¹, hoop
        # M − I = −M Λ⁻¹ (∇D)Λ, formed from D's gradient so that a small D leaves H₀ to round-off of its own size
        a_l = np.stack([a[0] / lz, a[1] / lz, a[2], a[3]])
        mi = -np.stack([m[0] * a_l[0] + m[1] * a_l[2], m[0] * a_l[1] + m[1] * a_l[3],
                        m[2] * a_l[0] + m[3] * a_l[2], m[2] * a_l[1] + m[3] * a_l[3], a[4] / (1.0 + a[4])])
        H0 = np.stack([lz * mi[0] + self.H0[0], lz * mi[1], mi[2], mi[3], mi[4]])  # Λ M − I = Λ(M − I) + Λ − I
        B, mt = self.B, m.transpose(1, 2, 0)[..., None]  # (E, Q, 5, 1)
        composed = np.stack([B[:, :, 0] * mt[:, :, 0] + B[:, :, 1] * mt[:, :, 2],
                             B[:, :, 0] * mt[:, :, 1] + B[:, :, 1] * mt[:, :, 3],
                             B[:, :, 2] * mt[:, :, 0] + B[:, :, 3] * mt[:, :, 2],
                             B[:, :, 2] * mt[:, :, 1] + B[:, :, 3] * mt[:, :, 3],
                             B[:, :, 4] * mt[:, :, 4]], axis=2)
        volume = m[4] * (m[0] * m[3] - m[1] * m[2])  # det M
        if not np.all(volume > 0.0):
            raise ValueError("the stress-free reference folds over (det(I + ∇D) ≤ 0 at a point of the band)")
        weights = self.weights / volume
        groups = (self.groups @ sp.diags((1.0 / volume).ravel())).tocsr()
        return BandKinematics(np.ascontiguousarray(composed), H0, weights, self.dofs, self.ndofs, groups,
                              self.per_element)

    def local_vector(self, P: np.ndarray) -> np.ndarray:
        """Σ_q P : ∂F/∂d per element (E, local DOFs), from the weighted first derivatives ``P`` (5, E, Q)."""
        return np.einsum("eqia,ieq->ea", self.B, P, optimize=True)

    def scatter(self, local: np.ndarray) -> np.ndarray:
        """The element vectors ``local`` (elements, local DOFs; :meth:`local_vector`'s, or their magnitudes: what
        a sum's round-off is relative to) summed into the global vector."""
        return np.bincount(self.dofs.T.ravel(), weights=local.ravel(), minlength=self.ndofs)

    def local_matrix(self, A: np.ndarray) -> np.ndarray:
        """Σ_q ∂F/∂dᵀ A ∂F/∂d per element (E, local DOFs, local DOFs), from the weighted second derivatives
        ``A`` (5, 5, E, Q)."""
        AB = A.transpose(2, 3, 0, 1) @ self.B  # (E, Q, 5, nloc)
        return np.sum(self.B.transpose(0, 1, 3, 2) @ AB, axis=1)

    def assemble(self, local: np.ndarray) -> sp.csr_matrix:
        """The global matrix of the element matrices ``local`` (E, local DOFs, local DOFs)."""
        indices, indptr, where = self.pattern
        data = np.bincount(where, weights=local.ravel(), minlength=indices.size)
        return sp.csr_matrix((data, indices, indptr), shape=(self.ndofs, self.ndofs))

    def rows(self, dJ: np.ndarray) -> sp.csr_matrix:
        """The derivative of the pointwise J in d, one row per quadrature point (elements·points × DOFs), from
        ``dJ`` = ∂J/∂F (5, E, Q)."""
        local = np.einsum("eqia,ieq->eqa", self.B, dJ, optimize=True)
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
