"""The wall as one structure problem: every layer of the stack on one set of DOFs.

Reading the stack from the lumen outward, thin layers sit on interface
lines and thick layers are radial bands (theory §1).  Line 0 is r = R; each
band ends on the next line.  When the stack has thick bands, the unknowns
are the displacement d = (d_z, d_r) of one conforming vector-Lagrange field
on all bands, and a thin layer's η IS d_r on its line (with d_z = 0 there);
with no band, the unknowns are η on line 0 alone.
"""

from __future__ import annotations

from collections.abc import Sequence

import attrs
import numpy as np
import scipy.sparse as sp
import skfem

from multilayer.geometry.contract import Geometry
from multilayer.geometry.mesh import lagrange_tri, wall_mesh
from multilayer.geometry.spaces import (
    BandSpace,
    LineSpace,
    line_prolongation,
    make_line_space,
    prolongation_dofs,
)
from multilayer.wall.checks import (
    LayerError,
    essential_problems,
    linearity_problem,
    matrix_problems,
    raised,
    state_problems,
)
from multilayer.wall.layer import Layer, LayerMatrices

#: the interface line of the lumen, r = R: the fluid's wall
LUMEN = 0


@attrs.frozen(eq=False)
class Placement:
    """Where one layer of the stack sits: its line (thin) or band (thick)."""

    index: int  #: position in the stack (``layers[index]`` of the case)
    layer: Layer
    line: int | None = None
    band: int | None = None
    name: str = ""  #: the layer's model name, for messages

    @property
    def where(self) -> str:
        """``layers[i] (model)``: the layer as a message names it."""
        return f"layers[{self.index}] ({self.name or type(self.layer).__name__})"


@attrs.define(eq=False)
class WallSpace:
    """DOFs of the whole wall and the maps from each line and band into them."""

    geometry: Geometry  #: the measure of every integral on the wall
    length: float
    radius: float
    order: int
    ndofs: int
    lines: list[LineSpace]  #: interface lines, 0 = lumen, then one per band boundary
    prolongations: list[sp.csr_matrix]  #: P_i: line i DOFs → wall DOFs
    bands: list[BandSpace]
    basis: skfem.CellBasis | None  #: vector basis on all bands (None: no band)
    placements: list[Placement]
    #: R_i = P_iᵀ as its own CSR matrix: wall DOFs → line i DOFs (a step restricts every step; ``P.T`` is a new
    #: matrix each time)
    restrictions: list[sp.csr_matrix] = attrs.field(init=False)

    def __attrs_post_init__(self):
        self.restrictions = [P.T.tocsr() for P in self.prolongations]

    @classmethod
    def build(cls, layers: Sequence[Layer], geometry: Geometry, length: float, radius: float, nz: int, order: int,
              band_cells: Sequence[int | None] = (), names: Sequence[str] = ()) -> WallSpace:
        """Place ``layers`` (lumen outward) and build the wall's spaces in ``geometry``'s measure.

        ``band_cells[i]`` is the radial cell count of ``layers[i]`` when it is
        thick; ``names[i]`` its model name, for messages.
        """
        placements: list[Placement] = []
        bands_spec: list[tuple[float, int]] = []
        for i, layer in enumerate(layers):
            name = names[i] if i < len(names) else ""
            if layer.thin:
                placements.append(Placement(i, layer, line=len(bands_spec), name=name))
            else:
                cells = (band_cells[i] if i < len(band_cells) else None) or 4
                placements.append(Placement(i, layer, band=len(bands_spec), name=name))
                bands_spec.append((float(layer.thickness), int(cells)))

        if not bands_spec:
            line = make_line_space(length, nz, order, radius, geometry)
            eye = sp.identity(line.ndofs, format="csr")
            return cls(geometry, length, radius, order, line.ndofs, [line], [eye], [], None, placements)

        mesh, band_elements, edges = wall_mesh(length, radius, nz, bands_spec)
        elem = skfem.ElementVector(lagrange_tri(order))
        basis = geometry.weighted(skfem.Basis(mesh, elem))
        bands = [
            BandSpace(basis=geometry.weighted(skfem.Basis(mesh, elem, elements=els)), r_inner=a, r_outer=b,
                      length=length, order=order, geometry=geometry)
            for els, a, b in zip(band_elements, edges[:-1], edges[1:])
        ]
        r_dofs = basis.split_indices()[1]
        zr = basis.doflocs[:, r_dofs]
        lines, prolongations = [], []
        for r_line in edges:
            line = make_line_space(length, nz, order, r_line, geometry)
            on = np.abs(zr[1] - r_line) < 1e-9 * max(r_line, 1.0)
            lines.append(line)
            prolongations.append(line_prolongation(line, r_dofs[on], zr[0, on], basis.N))
        return cls(geometry, length, radius, order, int(basis.N), lines, prolongations, bands, basis, placements)

    # -- where things are ---------------------------------------------------
    def space_of(self, p: Placement) -> LineSpace | BandSpace:
        return self.lines[p.line] if p.line is not None else self.bands[p.band]

    @property
    def outer_line(self) -> int:
        return len(self.lines) - 1

    def line_dofs(self, i: int) -> np.ndarray:
        """Wall DOFs of line i, in the line's own order."""
        return prolongation_dofs(self.prolongations[i])

    def line_load(self, i: int) -> np.ndarray:
        """∫ ψ dA on line i (the geometry's measure of the line), in wall numbering: the work vector of a unit
        pressure."""
        line = self.lines[i]
        return self.prolongations[i] @ skfem.asm(_unit_load, line.basis)

    def line_z_dofs(self, i: int) -> np.ndarray:
        """Wall d_z DOFs of line i, in the line's own order (the same nodes as :meth:`line_dofs`)."""
        z_dofs, r_dofs = self.basis.split_indices()
        return z_dofs[np.searchsorted(r_dofs, self.line_dofs(i))]

    def tangential_dofs_on(self, i: int) -> np.ndarray:
        """d_z DOFs on line i (held at zero under a thin layer)."""
        if self.basis is None:
            return np.zeros(0, dtype=np.int64)
        z_dofs = self.basis.split_indices()[0]
        r = self.basis.doflocs[1, z_dofs]
        return z_dofs[np.abs(r - self.lines[i].radius) < 1e-9 * max(self.lines[i].radius, 1.0)]

    # -- initial data -------------------------------------------------------
    def interpolate(self, fz, fr) -> np.ndarray:
        """Nodal interpolant of the vector field (fz, fr)(z, r) on the wall DOFs."""
        if self.basis is None:
            line = self.lines[0]
            return np.asarray(fr(z=line.z, r=np.full_like(line.z, line.radius), t=0.0), dtype=float)
        out = np.zeros(self.ndofs)
        for comp, f in zip(self.basis.split_indices(), (fz, fr)):
            z, r = self.basis.doflocs[:, comp]
            out[comp] = f(z=z, r=r, t=0.0)
        return out


@skfem.LinearForm
def _unit_load(v, w):
    return v


@attrs.define(eq=False)
class Stack:
    """The assembled stack: per-layer forms in wall numbering, their matrices' sums, the free DOFs.

    A nonlinear layer's damping and stiffness are its tangents at rest, so the sums are the wall's at rest.
    """

    space: WallSpace
    matrices: list[LayerMatrices]  #: one per layer, in stack order (their forces: :class:`LayerMatrices`)
    mass: sp.csr_matrix
    damping: sp.csr_matrix
    stiffness: sp.csr_matrix
    fixed: np.ndarray  #: essential DOFs, held at zero
    free: np.ndarray

    @property
    def linear(self) -> bool:
        """True when every layer's forces are linear: the wall's step matrix is constant for a Δt."""
        return all(m.linear for m in self.matrices)

    def force(self, d: np.ndarray) -> np.ndarray:
        """Σ_i f_i(d): the internal force of every layer at the displacement ``d`` (wall numbering)."""
        return sum((m.force(d) for m in self.matrices), np.zeros(self.space.ndofs))

    def tangent(self, d: np.ndarray) -> sp.csr_matrix:
        """Σ_i K_T,i(d): the wall's stiffness tangent at ``d``."""
        return sum((sp.csr_matrix(m.tangent(d)) for m in self.matrices), sp.csr_matrix(self.stiffness.shape)).tocsr()

    @classmethod
    def assemble(cls, space: WallSpace, radial_lines: Sequence[int] = (), pinned_lines: Sequence[int] = ()) -> Stack:
        """Every layer's matrices on its space, checked (:func:`layer_output`), summed in wall numbering.

        d_z is held at zero on the line of every thin layer and on ``radial_lines``
        (a fluid glued radially to a thick band: :meth:`Coupler.radial_lines`), whose
        ends are pinned as a thin layer's are (the fluid holds u_r = 0 at Γ's corners).
        On ``pinned_lines`` (a fluid on a thick band under no-slip) only the
        ends are held, in both components: the fluid domain keeps its length.

        Raises
        ------
        LayerError
            Naming the layer (``layers[i] (model)``) and what it returned wrong.
        """
        n = space.ndofs
        matrices: list[LayerMatrices] = []
        fixed = [np.zeros(0, dtype=np.int64)]
        for i in radial_lines:
            fixed += [space.tangential_dofs_on(i), space.line_dofs(i)[space.lines[i].end_dofs]]
        for i in pinned_lines:
            ends = space.lines[i].end_dofs
            fixed += [space.line_z_dofs(i)[ends], space.line_dofs(i)[ends]]
        for p in space.placements:
            own, ess = layer_output(p, space.space_of(p))
            if p.line is not None:
                P = space.prolongations[p.line]
                own = own.scattered(P)
                ess = space.line_dofs(p.line)[ess]
                fixed.append(space.tangential_dofs_on(p.line))
            matrices.append(own)
            fixed.append(ess)
        zero = sp.csr_matrix((n, n))
        M = sum((m.mass for m in matrices), zero).tocsr()
        C = sum((m.damping for m in matrices), zero).tocsr()
        K = sum((m.stiffness for m in matrices), zero).tocsr()
        fixed_all = np.unique(np.concatenate(fixed))
        free = np.setdiff1d(np.arange(n), fixed_all)
        return cls(space, matrices, M, C, K, fixed_all, free)

    def on_reference(self, reference: np.ndarray) -> Stack:
        """The stack whose layers that take a stress-free reference (:meth:`Layer.takes_reference`) are unloaded
        at the mesh moved by ``reference`` (wall numbering; each layer given its restriction, a thin one its
        line's); the other layers' forms kept (unloaded at the mesh).  The essential DOFs are the same.

        Raises
        ------
        LayerError
            Naming the layer whose forms on the reference fail (a reference that folds the band, or closes the
            channel at a membrane's line).
        """
        space = self.space
        matrices = list(self.matrices)
        for p in space.placements:
            if not type(p.layer).takes_reference():
                continue
            own = space.restrictions[p.line] @ reference if p.line is not None else reference
            try:
                forms = p.layer.forms_on_reference(space.space_of(p), own)
            except Exception as exc:  # the layer's own code: name it and say where it failed
                raise LayerError(p.where, [f"forms_on_reference raised {raised(exc)}"]) from exc
            matrices[p.index] = forms.scattered(space.prolongations[p.line]) if p.line is not None else forms
        zero = sp.csr_matrix((space.ndofs, space.ndofs))
        return Stack(space, matrices, sum((m.mass for m in matrices), zero).tocsr(),
                     sum((m.damping for m in matrices), zero).tocsr(), sum((m.stiffness for m in matrices), zero).tocsr(),
                     self.fixed, self.free)

    def zero_fixed(self, x: np.ndarray) -> np.ndarray:
        """A copy of the wall vector ``x`` with the essential DOFs set to zero."""
        x = np.array(x, dtype=float)
        x[self.fixed] = 0.0
        return x


def fluid_pinned_lines(layers: Sequence[Layer], fluid: bool) -> tuple[int, ...]:
    """The lines whose ends a fluid pins in both components (:meth:`Stack.assemble`'s ``pinned_lines``): the
    lumen's, when a fluid lies directly on a thick first layer (the fluid domain keeps its length)."""
    return (LUMEN,) if fluid and layers and not layers[0].thin else ()


def layer_output(p: Placement, space: LineSpace | BandSpace) -> tuple[LayerMatrices, np.ndarray]:
    """The forms and essential DOFs of the layer placed at ``p``, on its ``space``, checked.

    The checks of :mod:`multilayer.wall.checks`: sparse matrices of the
    space's shape, finite, symmetric; forms linear as the layer declares, and
    nonlinear ones returning forces and tangents of the space's shape at rest;
    essential DOFs integers in range.

    Raises
    ------
    LayerError
        ``layers[i] (model): damping must be a scipy sparse matrix, got float``,
        or what the layer's own code raised, with where.
    """
    n = space.ndofs
    try:
        own = p.layer.forms(space)
    except Exception as exc:  # the layer's own code: name it and say where it failed
        raise LayerError(p.where, [f"forms raised {raised(exc)}"]) from exc
    problems = matrix_problems(own, n)
    linearity = linearity_problem(p.layer, own)
    problems += [linearity] if linearity else []
    if not problems and not own.linear:
        problems += state_problems(own, n)
    try:
        ess = p.layer.essential_dofs(space)
    except Exception as exc:
        raise LayerError(p.where, [f"essential_dofs raised {raised(exc)}"]) from exc
    problems += essential_problems(ess, n)
    if problems:
        raise LayerError(p.where, problems)
    return own, np.asarray(ess, dtype=np.int64)
