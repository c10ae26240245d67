"""``wave-membrane``: the 1D wave equation on the interface line, ρ₁h η_tt = C1 η_zz + f.

The Koiter family with C0 = C2 = D0 = D1 = D2 = 0 (theory §1; the seed
writes the tension C1 as c²).  Ends pinned: η(0) = η(L) = 0.
"""

from __future__ import annotations

from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import LayerPlugin, Param
from multilayer_plugins.thin_shell import KoiterFamilyLayer, mass_params


def wave_membrane(density: float, thickness: float, tension: float) -> KoiterFamilyLayer:
    """A membrane of density ρ₁ (g/cm³), thickness h (cm) and tension C1 (dyn/cm).

    >>> wave_membrane(1.1, 0.1, 2.0e3).C1
    2000.0
    """
    return KoiterFamilyLayer(density=density, thickness=thickness, C1=tension)


@hookimpl
def multilayer_layers() -> list[LayerPlugin]:
    """The ``wave-membrane`` layer."""
    return [
        LayerPlugin(
            name="wave-membrane",
            factory=wave_membrane,
            params=(
                *mass_params("membrane"),
                Param("tension", "C1", "dyn/cm", ge=0.0, doc="tension (the seed's c²)"),
            ),
            doc="Wave-equation membrane: ρ₁h η_tt = C1 η_zz + f, ends pinned.",
            thin=True,
            example={"density": 1.1, "thickness": 0.1, "tension": 2.0e4},
        )
    ]
