"""A small wall built at validation: what each layer returns is checked before any run.

The validator places the case's layers on a wall of :data:`PROBE_NZ` cells
along z (one radial cell per band, the case's geometry and order) and has
each layer assemble on it, with the checks of :func:`multilayer.wall.stack.layer_output`
(sparse matrices of the space's shape, finite, symmetric; essential DOFs in
range).  A plugin's mistake is then reported by ``multilayer validate`` at
the layer's key path.  The same checks run on the real wall when a run
starts, for what only shows at full size.
"""

from __future__ import annotations

from collections.abc import Sequence

from multilayer.geometry.contract import Geometry
from multilayer.wall.checks import LayerError
from multilayer.wall.layer import Layer
from multilayer.wall.stack import WallSpace, layer_output

#: Cells along z of the probe wall.
PROBE_NZ = 2


def probe(layers: Sequence[Layer], names: Sequence[str], geometry: Geometry, length: float, radius: float,
          order: int) -> dict[int, list[str]]:
    """What is wrong with what each layer returns on a small wall in ``geometry``, by position in the stack.

    >>> import numpy as np
    >>> from skfem import BilinearForm
    >>> from multilayer.wall.layer import LayerMatrices, ThinLayer
    >>> class Flat(Geometry):  # a planar measure, dV = dz dr
    ...     def weight(self, r):
    ...         return np.ones_like(np.asarray(r, dtype=float))
    >>> mass = BilinearForm(lambda eta, psi, w: eta * psi)
    >>> class Spring(ThinLayer):  # a wall on springs
    ...     def forms(self, space):
    ...         M = mass.assemble(space.basis).tocsr()
    ...         return LayerMatrices(M, 0.0 * M, 1e5 * M)
    >>> class Undamped(ThinLayer):  # its damping a number, not a matrix
    ...     def forms(self, space):
    ...         M = mass.assemble(space.basis).tocsr()
    ...         return LayerMatrices(M, 0.0, 1e5 * M)
    >>> probe([Spring(), Spring()], ["a", "b"], Flat(), 6.0, 0.5, 2)
    {}
    >>> probe([Spring(), Undamped()], ["a", "b"], Flat(), 6.0, 0.5, 2)
    {1: ['damping must be a scipy sparse matrix, got float']}
    """
    space = WallSpace.build(layers, geometry, length, radius, PROBE_NZ, order, [1] * len(layers), names)
    found = {}
    for p in space.placements:
        try:
            layer_output(p, space.space_of(p))
        except LayerError as exc:
            found[p.index] = exc.problems
    return found
