"""Stand-in plugins with the built-ins' names and parameter schemas.

They let the case-file tests check validation without depending on the
real models: ``Registry.load(extra=[fake_plugins], entry_points=False)``.
"""

from __future__ import annotations

import attrs
import scipy.sparse as sp

from multilayer.fluid.contract import Fluid
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import CouplerPlugin, FluidPlugin, LayerPlugin, Param
from multilayer.wall.layer import LayerMatrices, ThickLayer, ThinLayer

# the real geometry and pressure ends: every case has a geometry and two ends, and these have no model behind them
from multilayer_plugins.planar import multilayer_geometries  # noqa: F401
from multilayer_plugins.pressure import multilayer_boundaries  # noqa: F401

DENSITY = Param("density", "ρ", "g/cm³", gt=0.0, doc="density")
THICKNESS = Param("thickness", "h", "cm", gt=0.0, doc="thickness")
YOUNG = Param("young", "E", "dyn/cm²", gt=0.0, doc="Young's modulus")
POISSON = Param("poisson", "σ", gt=-1.0, lt=0.5, doc="Poisson ratio")


@attrs.frozen
class Model:
    """Any fake fluid or coupler: its parameters, nothing else."""

    params: dict = attrs.field(factory=dict)

    def energy(self, setup, state):  # a coupler's methods (never called)
        return {}

    def evolve(self, setup, state):
        return iter(())


def model(**params: object) -> Model:
    return Model(params)


# stand-ins pass validation's checks of the type a factory returns (they are never run)
Fluid.register(Model)


def _identity(space) -> LayerMatrices:
    n = int(space.ndofs)
    return LayerMatrices(sp.identity(n, format="csr"), sp.csr_matrix((n, n)), sp.identity(n, format="csr"))


class Thin(ThinLayer):
    """Any fake thin layer: its parameters, and matrices the validator's small wall accepts."""

    def __init__(self, **params: object):
        self.params = params

    def forms(self, space) -> LayerMatrices:
        return _identity(space)


class Band(ThickLayer):
    def __init__(self, thickness: float):
        self.thickness = thickness

    def forms(self, space) -> LayerMatrices:
        return _identity(space)


def band(**params: object) -> Band:
    if params["young"] > 1e12:
        raise ValueError("young and poisson give no positive wave speed")
    return Band(params["thickness"])


class NeedsFluid(Model):
    def check_case(self, case: object) -> list[str]:
        return [] if case.fluid is not None else ["kinematic-splitting needs a fluid"]


@hookimpl
def multilayer_layers():
    return [
        LayerPlugin("wave-membrane", Thin, (DENSITY, THICKNESS, Param("tension", "C1", "dyn", gt=0.0)), "membrane"),
        LayerPlugin(
            "koiter-shell",
            Thin,
            (DENSITY, THICKNESS, YOUNG, POISSON, Param("viscosity", "D1", "dyn·s/cm²", default=0.0, ge=0.0)),
            "shell",
        ),
        LayerPlugin("linear-elastic", band, (DENSITY, THICKNESS, YOUNG, POISSON), "band", thin=False),
    ]


@hookimpl
def multilayer_fluids():
    params = (DENSITY, Param("viscosity", "μ", "P", gt=0.0))
    return [FluidPlugin("navier-stokes", model, params, "NS"), FluidPlugin("stokes", model, params, "Stokes")]


@hookimpl
def multilayer_couplers():
    return [
        CouplerPlugin("structure-only", model, (), "walls alone"),
        CouplerPlugin("kinematic-splitting", NeedsFluid, (), "the scheme"),
        CouplerPlugin("fluid-only", model, (), "rigid walls"),
    ]
