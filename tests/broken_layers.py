"""Layer plugins with one mistake each, as a plugin author could make it (and one without).

The tests register this module (``Registry.load(extra=[broken_layers])`` or
``--plugin broken_layers``) and check that each mistake is named: by the
validator, by the wall's assembly when a run starts, and by the
conformance kit (:mod:`multilayer.testing`).  ``MISTAKES`` says what each
must be told.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import skfem

from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import LayerPlugin, Param
from multilayer.wall.layer import LayerMatrices, ThickLayer, ThinLayer


@skfem.BilinearForm
def mass(eta, psi, w):
    return eta * psi


class Spring(ThinLayer):
    """ρ η_tt + k η = f: a correct thin layer, the base of the broken ones."""

    def __init__(self, density: float = 1.0, stiffness: float = 1e4):
        self.density, self.stiffness = density, stiffness

    def forms(self, space):
        M = mass.assemble(space.basis).tocsr()
        return LayerMatrices(self.density * M, 0.0 * M, self.stiffness * M)


class WrongShape(Spring):
    def forms(self, space):
        good = super().forms(space)
        n = space.ndofs + 1
        return LayerMatrices(sp.csr_matrix((n, n)), good.damping, good.stiffness)


class FloatDamping(Spring):
    def forms(self, space):
        good = super().forms(space)
        return LayerMatrices(good.mass, 0.0, good.stiffness)


class DenseStiffness(Spring):
    def forms(self, space):
        good = super().forms(space)
        return LayerMatrices(good.mass, good.damping, good.stiffness.toarray())


class Asymmetric(Spring):
    def forms(self, space):
        good = super().forms(space)
        n = space.ndofs
        skew = sp.csr_matrix(([self.stiffness], ([0], [1])), shape=(n, n))
        return LayerMatrices(good.mass, good.damping, (good.stiffness + skew).tocsr())


class Indefinite(Spring):
    def forms(self, space):
        good = super().forms(space)
        return LayerMatrices(good.mass, good.damping, -good.stiffness)


class FloatEssential(Spring):
    def essential_dofs(self, space):
        return space.end_dofs.astype(float)


class EssentialOutOfRange(Spring):
    def essential_dofs(self, space):
        return np.array([0, space.ndofs + 3])


class NanOnFineMesh(Spring):
    """Right on a small space, NaN on a fine one: only a run on a real mesh shows it."""

    def forms(self, space):
        good = super().forms(space)
        return LayerMatrices(good.mass, good.damping, good.stiffness * (np.nan if space.ndofs > 16 else 1.0))


class NoForms(ThinLayer):
    def __init__(self, density: float = 1.0, stiffness: float = 1e4):
        self.density = density


class Raises(Spring):
    def forms(self, space):
        raise KeyError("stiffness_table")


class NanInATube(Spring):
    """Right in the planar channel, non-finite where the measure varies with r (a hoop term gone wrong)."""

    def forms(self, space):
        good = super().forms(space)
        if not space.geometry.radial_power:
            return good
        return LayerMatrices(good.mass, good.damping, good.stiffness * np.nan)


class Band(ThickLayer):
    """A thick layer, registered as thin by mistake."""

    thickness = 0.1

    def __init__(self, density: float = 1.0, stiffness: float = 1e4):
        self.density = density

    def forms(self, space):
        raise AssertionError("never reached: the kind is checked first")


def not_a_layer(density: float = 1.0, stiffness: float = 1e4) -> dict:
    return {"density": density}


DENSITY = Param("density", "ρh", "g/cm²", gt=0.0, doc="areal mass")
STIFFNESS = Param("stiffness", "k", "dyn/cm³", default=1e4, gt=0.0, doc="spring stiffness")

#: name, factory, what the validator and the assembly say (after ``layers[0]``), what the kit says
MISTAKES = [
    ("broken-shape", WrongShape, "mass has shape (6, 6); expected (5, 5) for its space", "mass has shape"),
    ("broken-float-damping", FloatDamping, "damping must be a scipy sparse matrix, got float",
     "damping must be a scipy sparse matrix, got float"),
    ("broken-dense", DenseStiffness, "stiffness must be a scipy sparse matrix, got ndarray",
     "stiffness must be a scipy sparse matrix, got ndarray"),
    ("broken-asymmetric", Asymmetric, "stiffness is not symmetric", "stiffness is not symmetric"),
    ("broken-essential-float", FloatEssential, "essential_dofs must be integers, got float64",
     "essential_dofs must be integers, got float64"),
    ("broken-essential-range", EssentialOutOfRange, "essential_dofs has indices outside 0..4: [8]",
     "essential_dofs has indices outside"),
    ("broken-abstract", NoForms, "NoForms does not implement forms (abstract in Layer)",
     "NoForms does not implement forms (abstract in Layer)"),
    ("broken-raises", Raises, "forms raised KeyError: 'stiffness_table' (", "forms raised KeyError: 'stiffness_table'"),
    ("broken-not-a-layer", not_a_layer, None, "the factory returned dict; expected a ThinLayer"),
    ("broken-kind", Band, "the factory returned a thick layer (Band); expected a ThinLayer",
     "the factory returned a thick layer (Band); expected a ThinLayer"),
]
#: mistakes that validation lets through: (name, factory, the kit's check that fails, what it says)
KIT_ONLY = [
    ("broken-in-a-tube", NanInATube, "matrices", "order 1 (axisymmetric): stiffness has non-finite entries"),
    ("broken-indefinite", Indefinite, "matrices", "stiffness is not positive semi-definite: smallest eigenvalue"),
    ("broken-on-fine-mesh", NanOnFineMesh, "coupled-run", "the run failed: setting up the scene failed: "
     "layers[0] (broken-on-fine-mesh): stiffness has non-finite entries (nan or inf)"),
]
#: schema mistakes: (name, params, what the kit says)
SCHEMA_MISTAKES = [
    ("broken-schema-doc", (DENSITY, Param("stiffness", "k", "dyn/cm³", default=1e4, gt=0.0)),
     "parameter 'stiffness' has no doc"),
    ("broken-schema-unit", (DENSITY, Param("stiffness", "k", default=1e4, gt=0.0, doc="spring stiffness")),
     "float parameter 'stiffness' has no unit"),
    ("broken-schema-default", (DENSITY, Param("stiffness", "k", "dyn/cm³", default=-1.0, gt=0.0, doc="stiffness")),
     "default of 'stiffness' (-1.0) is not valid against its own schema: expected a number > 0.0"),
]


@hookimpl
def multilayer_layers():
    records = [LayerPlugin("good-spring", Spring, (DENSITY, STIFFNESS), "A wall on springs.")]
    records += [LayerPlugin(name, factory, (DENSITY, STIFFNESS), "Broken on purpose.")
                for name, factory, *_ in MISTAKES + KIT_ONLY]
    records += [LayerPlugin(name, Spring, params, "Broken on purpose.") for name, params, _ in SCHEMA_MISTAKES]
    return records
