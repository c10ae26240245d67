"""``axisymmetric``: the meridian plane of a tube — every field revolves about the axis r = 0.

The (z, r) half-plane is a meridian of a swirl-free axisymmetric scene, so
every integral is over the tube: dV = 2π r dz dr, a line r = R has the
measure 2πR dz.  The constant 2π is kept (not dropped), so that energies
are in erg, forces in dyn and flow rates in cm³/s, as a 3D code reports
them.  Beyond the measure a tube has hoop terms (theory §11): u_r/r in the
fluid's divergence and strain rate, d_r/r in a band's strain; the fluid and
the bands read them from ``radial_power`` = 1 of their space's geometry.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from multilayer.geometry.contract import Geometry
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import GeometryPlugin


class Axisymmetric(Geometry):
    """The tube: weight(r) = 2π r.

    >>> g = Axisymmetric()
    >>> g.weight([0.0, 0.5]).round(6).tolist(), round(g.line_weight(0.5), 6), g.radial_power
    ([0.0, 3.141593], 3.141593, 1)
    >>> float(g.stretch(1.1))  # the volume element (J r̂)(J dr̂) under the ALE map r = J r̂
    1.2100000000000002
    """

    name = "axisymmetric"
    radial_power = 1
    integral_units: ClassVar[dict[str, str]] = {"energy": "erg", "flow_rate": "cm³/s"}

    def weight(self, r):
        return 2.0 * math.pi * np.asarray(r, dtype=float)


@hookimpl
def multilayer_geometries():
    return [GeometryPlugin(name="axisymmetric", factory=Axisymmetric,
                           doc="A tube: the (z, r) plane is a meridian, every integral over the tube "
                               "(dV = 2πr dz dr), with the hoop terms u_r/r and d_r/r.")]
