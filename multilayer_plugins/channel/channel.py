"""The reference channel Ω̂ = (0, L) × (0, R): mesh, spaces and boundary DOF sets.

The fluid is assembled on this fixed mesh for the whole run (theory §2, the
seed's choice); only coefficient fields change from step to step.  The
velocity space is Taylor–Hood P2/P1 (``order=2``) or MINI P1b/P1
(``order=1``), so that the wall's u_r DOFs coincide with the DOFs of the
interface line's 1D Lagrange space of the same order (theory §3): they are
mapped onto its canonical numbering by :func:`multilayer.geometry.spaces.line_prolongation`.
"""

from __future__ import annotations

import attrs
import numpy as np
import scipy.sparse as sp
import skfem

from multilayer.geometry.contract import Geometry
from multilayer.geometry.mesh import channel_mesh
from multilayer.geometry.spaces import LineSpace, line_prolongation, make_line_space

VELOCITY_ELEMENTS = {2: skfem.ElementTriP2, 1: skfem.ElementTriMini}

#: Degree of the triangle quadrature in the planar channel (6 points).  It
#: integrates J ∇^η·u against the P1 pressure exactly for both elements
#: (degree ≤ 4 on Ω̂ when η is of the element's order), so the discrete
#: mass balance is exact.
QUADRATURE_ORDER = 4


def quadrature_order(geometry: Geometry) -> int:
    """The degree that keeps the divergence row exact in ``geometry``: 4 + 3k (13 points in a tube).

    In a tube the weighted divergence J²r̂ ∇^η·u + J u_r (J² = ((R + η)/R)², the
    weight r̂, the hoop term) against a P1 pressure has degree 7 for P2 (6 for MINI).

    >>> from multilayer_plugins.planar import Planar
    >>> quadrature_order(Planar())
    4
    """
    return QUADRATURE_ORDER + 3 * geometry.radial_power


def line_sampling(line: LineSpace, z: np.ndarray, cell: np.ndarray) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Matrices (S, S_z) with S η = η(z) and S_z η = η'(z) for a line vector η.

    ``cell`` is the index of the line element holding each point (points on
    a cell boundary may name either neighbour).

    >>> from multilayer_plugins.planar import Planar
    >>> line = make_line_space(2.0, 2, 2, 0.5, Planar())
    >>> S, Sz = line_sampling(line, np.array([0.5, 1.5]), np.array([0, 1]))
    >>> eta = line.z ** 2
    >>> (S @ eta).tolist(), (Sz @ eta).tolist()
    ([0.25, 2.25], [1.0, 3.0])
    """
    nodes, ends = line.basis.mesh.p[0], line.basis.mesh.t
    left = nodes[ends[0, cell]]
    width = nodes[ends[1, cell]] - left  # the reference segment's orientation
    s = ((z - left) / width)[None, :]
    rows, cols, val, der = [], [], [], []
    for i in range(line.basis.Nbfun):
        phi, dphi = line.basis.elem.lbasis(s, i)
        rows.append(np.arange(len(z)))
        cols.append(line.basis.element_dofs[i, cell])
        val.append(phi)
        der.append(dphi[0] / width)
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    shape = (len(z), line.ndofs)
    S = sp.csr_matrix((np.concatenate(val), (rows, cols)), shape=shape)
    Sz = sp.csr_matrix((np.concatenate(der), (rows, cols)), shape=shape)
    return S, Sz


@attrs.frozen(eq=False)
class Channel:
    """Mesh, bases and DOF sets of the reference channel.

    Build it with :meth:`build`.  Unknowns are ordered ``x = (u, p)``:
    ``velocity.N`` velocity DOFs (z and r components interleaved, as
    scikit-fem numbers a vector basis), then ``pressure.N`` pressure DOFs.

    >>> from multilayer_plugins.planar import Planar
    >>> ch = Channel.build(Planar(), 6.0, 0.5, nz=6, nr=2, order=2)
    >>> ch.line.ndofs, len(ch.wall_r), ch.prolongation.shape == (ch.velocity.N, ch.line.ndofs)
    (13, 13, True)
    """

    geometry: Geometry  #: the measure every basis below carries in its quadrature weights
    length: float
    radius: float
    order: int
    mesh: skfem.MeshTri
    velocity: skfem.CellBasis  #: vector (u_z, u_r) basis, P2 or P1b
    pressure: skfem.CellBasis  #: scalar P1 basis, same quadrature
    inlet: skfem.FacetBasis  #: velocity basis on the facets z = 0
    outlet: skfem.FacetBasis  #: velocity basis on the facets z = L
    line: LineSpace  #: the interface line r = R
    prolongation: sp.csr_matrix  #: P: line DOF i is velocity DOF P[:, i] (a wall u_r DOF)
    wall_z: np.ndarray  #: u_z DOFs on r = R
    wall_r: np.ndarray  #: u_r DOFs on r = R, corners included
    normal_r: np.ndarray  #: u_r DOFs on the axis, inlet and outlet (always 0)
    rhat: np.ndarray  #: r̂ at the quadrature points (nelems × nqp)
    eta_at_quad: sp.csr_matrix  #: line vector → η at the quadrature points (flattened)
    eta_z_at_quad: sp.csr_matrix  #: line vector → η_z at the quadrature points
    ends: tuple[int, int]  #: line DOFs at z = 0 and z = L
    #: Pᵀ as its own CSR matrix: velocity DOFs → line DOFs (``P.T`` would be a new matrix at every trace)
    restriction: sp.csr_matrix = attrs.field(init=False)

    def __attrs_post_init__(self):
        object.__setattr__(self, "restriction", self.prolongation.T.tocsr())

    @classmethod
    def build(
        cls,
        geometry: Geometry,
        length: float,
        radius: float,
        nz: int,
        nr: int,
        order: int = 2,
        grading: float = 1.0,
        line: LineSpace | None = None,
    ) -> Channel:
        """The channel of ``nz`` × ``nr`` cells (graded toward the wall) and its spaces, in ``geometry``'s measure.

        ``line`` is the interface line's space if the caller already has it
        (it must be the canonical one of :func:`multilayer.geometry.spaces.make_line_space`).
        """
        if order not in VELOCITY_ELEMENTS:
            raise ValueError(f"fluid element order must be 1 (MINI) or 2 (Taylor–Hood), got {order!r}")
        mesh = channel_mesh(length, radius, nz, nr, grading)
        velocity = skfem.Basis(mesh, skfem.ElementVector(VELOCITY_ELEMENTS[order]()), intorder=quadrature_order(geometry))
        pressure = geometry.weighted(skfem.Basis(mesh, skfem.ElementTriP1(), quadrature=velocity.quadrature))
        geometry.weighted(velocity)
        tol = 1e-9 * max(length, radius)
        facets = {
            name: mesh.facets_satisfying(test, boundaries_only=True)
            for name, test in (
                ("inlet", lambda x: x[0] < tol),
                ("outlet", lambda x: x[0] > length - tol),
            )
        }
        inlet = geometry.weighted(skfem.FacetBasis(mesh, velocity.elem, facets=facets["inlet"]))
        outlet = geometry.weighted(skfem.FacetBasis(mesh, velocity.elem, facets=facets["outlet"]))

        z, r = velocity.doflocs  # NaN at MINI bubbles: never on a boundary
        with np.errstate(invalid="ignore"):
            comp_z, comp_r = velocity.split_indices()
            on = {
                "wall": np.abs(r - radius) < tol,
                "axis": np.abs(r) < tol,
                "ends": (np.abs(z) < tol) | (np.abs(z - length) < tol),
            }
        wall_z = np.intersect1d(comp_z, np.flatnonzero(on["wall"]))
        wall_r = np.intersect1d(comp_r, np.flatnonzero(on["wall"]))
        normal_r = np.intersect1d(comp_r, np.flatnonzero(on["axis"] | on["ends"]))

        if line is None:
            line = make_line_space(length, nz, order, radius, geometry)
        elif (line.order != order or abs(line.radius - radius) > tol or abs(line.length - length) > tol
              or line.geometry is not geometry):
            raise ValueError("the interface line space does not match the channel")
        P = line_prolongation(line, wall_r, z[wall_r], velocity.N)

        # η depends on ẑ only: sample the line space at the z of every
        # quadrature point, in the line cell under the triangle.
        xq = velocity.global_coordinates()
        zq, rq = np.asarray(xq[0]), np.asarray(xq[1])
        segments = line.basis.mesh.p[0, line.basis.mesh.t]  # (2, line cells)
        by_z = np.argsort(segments.min(axis=0))
        starts = segments.min(axis=0)[by_z]
        centroid_z = mesh.p[0, mesh.t].mean(axis=0)
        cell = by_z[np.clip(np.searchsorted(starts, centroid_z) - 1, 0, len(starts) - 1)]
        cells = np.repeat(cell, zq.shape[1])
        S, Sz = line_sampling(line, zq.ravel(), cells)
        end0 = int(np.argmin(line.z))
        end1 = int(np.argmax(line.z))
        return cls(
            geometry=geometry,
            length=length,
            radius=radius,
            order=order,
            mesh=mesh,
            velocity=velocity,
            pressure=pressure,
            inlet=inlet,
            outlet=outlet,
            line=line,
            prolongation=P,
            wall_z=wall_z,
            wall_r=wall_r,
            normal_r=normal_r,
            rhat=rq,
            eta_at_quad=S,
            eta_z_at_quad=Sz,
            ends=(end0, end1),
        )

    @property
    def nu(self) -> int:
        """Number of velocity DOFs."""
        return int(self.velocity.N)

    @property
    def ndofs(self) -> int:
        """Number of unknowns (u, p)."""
        return int(self.velocity.N + self.pressure.N)

    @property
    def quad_shape(self) -> tuple[int, int]:
        """(elements, quadrature points per element)."""
        return self.rhat.shape

    def wall_trace(self, u: np.ndarray) -> np.ndarray:
        """The wall's u_r as a line vector: v = Pᵀ u."""
        return self.restriction @ u

    def interpolate(self, velocity) -> np.ndarray:
        """Velocity DOFs of the interpolant of ``velocity(z, r) -> (u_z, u_r)`` on Ω̂.

        Nodal at the Lagrange DOFs; a MINI bubble takes the value that makes
        the interpolant exact at the element's centroid.
        """
        basis = self.velocity
        x = np.zeros(basis.N)
        nodal = np.flatnonzero(~np.isnan(basis.doflocs[0]))
        comp_z, comp_r = basis.split_indices()
        for comp, dofs in ((0, comp_z), (1, comp_r)):
            picked = np.intersect1d(dofs, nodal)
            x[picked] = velocity(*basis.doflocs[:, picked])[comp]
        if self.order == 1:
            centroid = self.mesh.p[:, self.mesh.t].mean(axis=1)
            values = velocity(*centroid)
            vertex = basis.element_dofs[:6]  # (z, r) of the three vertices
            for comp in (0, 1):
                linear = x[vertex[comp::2]].mean(axis=0)
                x[basis.element_dofs[6 + comp]] = values[comp] - linear
        return x
