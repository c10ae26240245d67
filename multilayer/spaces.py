"""Function spaces the core hands to layers and fluids."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import skfem

from multilayer.interfaces import LineSpace
from multilayer.mesh import lagrange_line, line_mesh, match_by_z


def make_line_space(length: float, nz: int, order: int, radius: float) -> LineSpace:
    """The canonical 1D space of an interface line r = ``radius``.

    Every field that shares the line (thin layer, fluid u_r trace, thick d_r)
    maps its own DOFs onto this numbering with :func:`line_prolongation`.

    >>> s = make_line_space(6.0, 3, 2, 0.5)
    >>> int(s.ndofs), s.end_dofs.tolist()
    (7, [0, 3])
    """
    basis = skfem.Basis(line_mesh(length, nz), lagrange_line(order))
    return LineSpace(basis=basis, radius=radius, length=length, order=order)


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
