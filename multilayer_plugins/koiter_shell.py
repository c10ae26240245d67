"""``koiter-shell``: the (visco)elastic cylindrical Koiter shell of theory §1.

    ρ₁h η_tt + C0 η − C1 η_zz + C2 η_zzzz + D0 η_t − D1 η_tzz + D2 η_tzzzz = f

A case gives either the material (``young``, ``poisson``, optionally
``radius``, ``viscous_young``, ``viscous_poisson``), from which the
coefficients follow by theory §1, or the coefficients ``C0``, ``C1``, ``C2``
(and optionally ``D0``, ``D1``, ``D2``) directly — never a mix of the two.
Without ``radius`` the shell takes the radius of the line it is placed on.
"""

from __future__ import annotations

from typing import Any

import attrs

from multilayer.geometry.spaces import LineSpace
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import LayerPlugin, Param
from multilayer.wall.layer import LayerMatrices, ThinLayer
from multilayer_plugins.thin_shell import KoiterFamilyLayer, mass_params

_poisson = [attrs.validators.gt(-1.0), attrs.validators.lt(0.5)]


@attrs.frozen
class KoiterShell(ThinLayer):
    """A Koiter shell given by its material; the coefficients wait for the radius.

    >>> from multilayer.geometry.spaces import make_line_space
    >>> shell = KoiterShell(density=1.1, thickness=0.1, young=1e6, poisson=0.3)
    >>> shell.at_radius(0.5) == KoiterFamilyLayer.from_young_poisson(1.1, 0.1, 1e6, 0.3, 0.5)
    True
    >>> from multilayer_plugins.planar import Planar
    >>> shell.forms(make_line_space(6.0, 4, 1, 0.5, Planar())).stiffness.shape
    (5, 5)
    """

    density: float = attrs.field(converter=float, validator=attrs.validators.gt(0.0))  #: ρ₁ (g/cm³)
    thickness: float = attrs.field(converter=float, validator=attrs.validators.gt(0.0))  #: h (cm)
    young: float = attrs.field(converter=float, validator=attrs.validators.gt(0.0))  #: E (dyn/cm²)
    poisson: float = attrs.field(converter=float, validator=_poisson)  #: σ, in (−1, 0.5)
    #: R (cm); None: the radius of the line the shell is placed on
    radius: float | None = attrs.field(
        default=None,
        converter=attrs.converters.optional(float),
        validator=attrs.validators.optional(attrs.validators.gt(0.0)),
    )
    #: E_v (dyn·s/cm²), the viscous counterpart of E
    viscous_young: float = attrs.field(default=0.0, converter=float, validator=attrs.validators.ge(0.0))
    #: σ_v, the viscous counterpart of σ (defaults to σ)
    viscous_poisson: float = attrs.field(
        default=attrs.Factory(lambda self: self.poisson, takes_self=True), converter=float, validator=_poisson
    )

    def at_radius(self, radius: float) -> KoiterFamilyLayer:
        """The shell's coefficients on a line of radius ``radius`` (cm), unless it has its own."""
        return KoiterFamilyLayer.from_young_poisson(
            self.density, self.thickness, self.young, self.poisson,
            self.radius if self.radius is not None else radius,
            self.viscous_young, self.viscous_poisson,
        )

    def forms(self, space: LineSpace) -> LayerMatrices:
        """The forms of :class:`KoiterFamilyLayer` at ``space.radius`` (or the shell's own R)."""
        return self.at_radius(space.radius).forms(space)

    def long_wave_stiffness(self, radius: float | None = None) -> float:
        """C0 (dyn/cm³) at the shell's radius, or at ``radius`` (cm) when it has none."""
        if self.radius is None and radius is None:
            raise ValueError("the shell takes its line's radius: pass radius= to long_wave_stiffness")
        return self.at_radius(radius).C0


_MATERIAL = ("young", "poisson", "radius", "viscous_young", "viscous_poisson")
_COEFFICIENTS = ("C0", "C1", "C2", "D0", "D1", "D2")


def koiter_shell(**params: Any) -> ThinLayer:
    """The layer of a ``koiter-shell`` case entry (missing or None keys are not given).

    >>> koiter_shell(density=1.0, thickness=1.0, C0=1.0, C1=0.0, C2=2.0).C2
    2.0
    >>> koiter_shell(density=1.0, thickness=1.0, young=1.0, C0=1.0)
    Traceback (most recent call last):
    ...
    ValueError: give either young and poisson or C0, C1 and C2, not both; got young and C0
    """
    given = {k: v for k, v in params.items() if v is not None}
    material = [k for k in _MATERIAL if k in given]
    coefficients = [k for k in _COEFFICIENTS if k in given]
    if material and coefficients:
        raise ValueError(
            "give either young and poisson or C0, C1 and C2, not both; "
            f"got {', '.join(material)} and {', '.join(coefficients)}"
        )
    if coefficients:
        missing = [k for k in ("C0", "C1", "C2") if k not in given]
        if missing:
            raise ValueError(
                f"the coefficients C0, C1 and C2 go together; missing {', '.join(missing)}"
            )
        return KoiterFamilyLayer(**given)
    missing = [k for k in ("young", "poisson") if k not in given]
    if missing:
        raise ValueError(
            f"give young and poisson (or C0, C1 and C2); missing {', '.join(missing)}"
        )
    return KoiterShell(**given)


@hookimpl
def multilayer_layers() -> list[LayerPlugin]:
    """The ``koiter-shell`` layer."""
    return [
        LayerPlugin(
            name="koiter-shell",
            factory=koiter_shell,
            params=(
                *mass_params("shell"),
                Param("young", "E", "dyn/cm²", default=None, gt=0.0,
                      doc="Young's modulus (with poisson; excludes C0, C1, C2)"),
                Param("poisson", "σ", "1", default=None, gt=-1.0, lt=0.5,
                      doc="Poisson ratio, 0.5 excluded (with young)"),
                Param("radius", "R", "cm", default=None, gt=0.0,
                      doc="radius in the coefficients (with young; default: the line's radius)"),
                Param("viscous_young", "E_v", "dyn·s/cm²", default=None, ge=0.0,
                      doc="viscoelastic counterpart of young (with young; default 0)"),
                Param("viscous_poisson", "σ_v", "1", default=None, gt=-1.0, lt=0.5,
                      doc="viscoelastic counterpart of poisson (with young; default: poisson)"),
                Param("C0", "C0", "dyn/cm³", default=None, ge=0.0,
                      doc="coefficient of η (with C1, C2; excludes young)"),
                Param("C1", "C1", "dyn/cm", default=None,
                      doc="coefficient of −η_zz, >= −2√(C0·C2)"),
                Param("C2", "C2", "dyn·cm", default=None, ge=0.0, doc="coefficient of η_zzzz"),
                Param("D0", "D0", "dyn·s/cm³", default=None, ge=0.0,
                      doc="coefficient of η_t (with C0; default 0)"),
                Param("D1", "D1", "dyn·s/cm", default=None,
                      doc="coefficient of −η_tzz, >= −2√(D0·D2) (with C0; default 0)"),
                Param("D2", "D2", "dyn·s·cm", default=None, ge=0.0,
                      doc="coefficient of η_tzzzz (with C0; default 0)"),
            ),
            doc="Cylindrical Koiter shell: ρ₁h η_tt + C0 η − C1 η_zz + C2 η_zzzz + viscous terms = f.",
            thin=True,
            example={"density": 1.1, "thickness": 0.02, "young": 7.5e5, "poisson": 0.45, "viscous_young": 1.0e3},
        )
    ]
