"""``planar``: the seed's channel — the meridian plane is a 2D channel of unit depth.

Every integral is per unit depth: dV = dz dr, a line's measure is dz.  No
term beyond the measure: the fluid and the layers are the 2D models of
theory §1–§6 as they stand.
"""

from __future__ import annotations

import numpy as np

from multilayer.geometry.contract import Geometry
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import GeometryPlugin


class Planar(Geometry):
    """The planar channel: weight(r) = 1 (per unit depth).

    >>> Planar().weight([0.1, 0.5]).tolist(), Planar().line_weight(0.5)
    ([1.0, 1.0], 1.0)
    """

    name = "planar"
    radial_power = 0

    def weight(self, r):
        return np.ones(np.shape(r))


@hookimpl
def multilayer_geometries():
    return [GeometryPlugin(name="planar", factory=Planar,
                           doc="The seed's 2D channel: every integral per unit depth (dV = dz dr).")]
