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

    >>> from multilayer_plugins.linear_elastic import LinearElasticBand
    >>> from multilayer_plugins.planar import Planar
    >>> from multilayer_plugins.thin_shell import KoiterFamilyLayer
    >>> layers = [KoiterFamilyLayer(1.0, 0.1, C1=1.0), LinearElasticBand(1.0, 0.1, 1.0, 1.0)]
    >>> probe(layers, ["a", "b"], Planar(), 6.0, 0.5, 2)
    {}
    """
    space = WallSpace.build(layers, geometry, length, radius, PROBE_NZ, order, [1] * len(layers), names)
    found = {}
    for p in space.placements:
        try:
            layer_output(p, space.space_of(p))
        except LayerError as exc:
            found[p.index] = exc.problems
    return found
