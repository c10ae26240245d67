"""The spaces the core hands to layers and fluids: interface lines (1D) and radial bands of the wall."""

from __future__ import annotations

import attrs
import numpy as np
import scipy.sparse as sp
import skfem

from multilayer.geometry.contract import Geometry
from multilayer.geometry.mesh import lagrange_line, line_mesh, match_by_z


@attrs.frozen(eq=False)
class LineSpace:
    """The 1D space of a thin layer on the interface line r = ``radius``.

    ``basis`` is a scikit-fem basis of 1D Lagrange elements (order of the
    scene) on the z-partition shared by every field of the scene; its
    quadrature weights carry the ``geometry``'s measure of the line
    (:meth:`Geometry.weighted`), so a form assembled on it integrates over
    the line's surface (per unit depth in a planar channel, over 2πR in a tube).
    """

    basis: skfem.CellBasis
    radius: float
    length: float
    order: int
    geometry: Geometry

    @property
    def z(self) -> np.ndarray:
        """z coordinate of every DOF."""
        return self.basis.doflocs[0]

    @property
    def ndofs(self) -> int:
        return int(self.basis.N)

    @property
    def end_dofs(self) -> np.ndarray:
        """The DOFs at z = 0 and z = L."""
        tol = 1e-9 * self.length
        return np.flatnonzero((self.z < tol) | (self.z > self.length - tol))


@attrs.frozen(eq=False)
class BandSpace:
    """The space of a thick layer: the band ``r_inner < r < r_outer``.

    ``basis`` is a vector (d_z, d_r) Lagrange basis restricted to the band's
    elements; its numbering is that of the whole wall, so matrices assembled
    on it are already global.  Its quadrature weights carry the
    ``geometry``'s measure; a layer whose forms need more of the geometry
    (a tube's hoop strain d_r/r) reads ``geometry``.
    """

    basis: skfem.CellBasis
    r_inner: float
    r_outer: float
    length: float
    order: int
    geometry: Geometry

    @property
    def thickness(self) -> float:
        return self.r_outer - self.r_inner

    @property
    def ndofs(self) -> int:
        """Size of the numbering the band's matrices live in: the whole wall's, so (ndofs, ndofs)."""
        return int(self.basis.N)

    @property
    def dofs(self) -> np.ndarray:
        """Every DOF touched by the band."""
        return np.unique(self.basis.element_dofs)

    def side_dofs(self, side: str, component: str | None = None) -> np.ndarray:
        """DOFs on one side of the band: ``"z=0"``, ``"z=L"``, ``"inner"``, ``"outer"``.

        ``component`` is ``"z"``, ``"r"`` or ``None`` (both).
        """
        dofs = self.dofs
        z, r = self.basis.doflocs[:, dofs]
        tol = 1e-9 * max(self.length, self.r_outer)
        where = {
            "z=0": np.abs(z) < tol,
            "z=L": np.abs(z - self.length) < tol,
            "inner": np.abs(r - self.r_inner) < tol,
            "outer": np.abs(r - self.r_outer) < tol,
        }[side]
        picked = dofs[where]
        if component is None:
            return picked
        owned = self.basis.split_indices()[{"z": 0, "r": 1}[component]]
        return np.intersect1d(picked, owned)


def make_line_space(length: float, nz: int, order: int, radius: float, geometry: Geometry) -> LineSpace:
    """The canonical 1D space of an interface line r = ``radius``, in ``geometry``'s measure.

    Every field that shares the line (thin layer, fluid u_r trace, thick d_r)
    maps its own DOFs onto this numbering with :func:`line_prolongation`.

    >>> class Flat(Geometry):  # a planar measure, dV = dz dr
    ...     def weight(self, r):
    ...         return np.ones_like(np.asarray(r, dtype=float))
    >>> s = make_line_space(6.0, 3, 2, 0.5, Flat())
    >>> int(s.ndofs), s.end_dofs.tolist()
    (7, [0, 3])
    """
    basis = geometry.weighted(skfem.Basis(line_mesh(length, nz), lagrange_line(order)), radius)
    return LineSpace(basis=basis, radius=radius, length=length, order=order, geometry=geometry)


def line_prolongation(line: LineSpace, dofs: np.ndarray, dof_z: np.ndarray, n: int) -> sp.csr_matrix:
    """P (n × line.ndofs) with P[dofs[match], i] = 1: line DOF i is global DOF ``dofs[match]``.

    ``dofs`` are the candidate global DOFs on the line with z coordinates ``dof_z``.
    """
    idx = dofs[match_by_z(line.z, dof_z, line.length)]
    return sp.csr_matrix((np.ones(line.ndofs), (idx, np.arange(line.ndofs))), shape=(n, line.ndofs))


def prolongation_dofs(P: sp.spmatrix) -> np.ndarray:
    """The global DOF of each line DOF of a prolongation built by :func:`line_prolongation`.

    >>> P = sp.csr_matrix(([1.0, 1.0], ([4, 2], [0, 1])), shape=(5, 2))
    >>> prolongation_dofs(P).tolist()
    [4, 2]
    """
    return sp.csc_matrix(P).indices
