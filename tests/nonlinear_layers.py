"""A nonlinear thin layer, registered from the tests folder: a membrane on stiffening (cubic) springs.

    ρh η_tt + D0 η_t + D3 η_t³ − C1 η_zz + k η + k₃ η³ = f,      W(η) = ∫ ½C1 η_z² + ½k η² + ¼k₃ η⁴ dA

(the hoop force of a wall that stiffens as it stretches, k η + k₃ η³; a
cubic viscosity D3 η_t³ for a nonlinear damping).  Its forms are
:class:`~multilayer.wall.layer.NonlinearForms`: the force, the tangent and
the energy are assembled from η at the quadrature points, so the force is
the exact gradient of the discrete W and the tangent its exact Hessian.

The tests register this module (``Registry.load(extra=[nonlinear_layers])``)
as a third party would; ``LinearTwin`` is the same layer with k₃ = D3 = 0
written as linear forms, for comparisons of the Newton loop with the linear
step.
"""

from __future__ import annotations

from typing import Any

import attrs
import scipy.sparse as sp
import skfem

from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import LayerPlugin, Param
from multilayer.wall.layer import LayerMatrices, NonlinearForms, ThinLayer


@skfem.BilinearForm
def mass(eta, psi, w):
    """∫ η ψ."""
    return eta * psi


@skfem.BilinearForm
def laplace(eta, psi, w):
    """∫ η_z ψ_z."""
    return eta.grad[0] * psi.grad[0]


@skfem.LinearForm
def cubic_force(psi, w):
    """∫ x³ ψ at the field x (η for the spring, η_t for the viscosity)."""
    return w["x"] ** 3 * psi


@skfem.BilinearForm
def cubic_tangent(eta, psi, w):
    """∫ 3 x² η ψ: the derivative of :func:`cubic_force`."""
    return 3.0 * w["x"] ** 2 * eta * psi


@skfem.Functional
def quartic(w):
    """∫ ¼ x⁴: the energy whose gradient is :func:`cubic_force`."""
    return 0.25 * w["x"] ** 4


@attrs.frozen(eq=False)
class CubicSpringForms(NonlinearForms):
    """The linear forms (M, D0 M, k M + C1 ∫η_zψ_z) plus the cubic spring k₃ and the cubic viscosity D3."""

    basis: Any  #: the line's basis (its measure is the geometry's)
    cubic: float  #: k₃ (dyn/cm⁵)
    cubic_damping: float  #: D3 (dyn·s³/cm⁵)

    def _cubic(self, x):
        return cubic_force.assemble(self.basis, x=self.basis.interpolate(x))

    def _cubic_tangent(self, x):
        return cubic_tangent.assemble(self.basis, x=self.basis.interpolate(x))

    def elastic(self, d):
        return LayerMatrices.elastic(self, d) + self.cubic * float(quartic.assemble(self.basis,
                                                                                    x=self.basis.interpolate(d)))

    def force(self, d):
        return self.stiffness @ d + self.cubic * self._cubic(d)

    def tangent(self, d):
        return sp.csr_matrix(self.stiffness + self.cubic * self._cubic_tangent(d))

    def damping_force(self, v):
        return self.damping @ v + self.cubic_damping * self._cubic(v)

    def damping_tangent(self, v):
        return sp.csr_matrix(self.damping + self.cubic_damping * self._cubic_tangent(v))


class CubicSpringMembrane(ThinLayer):
    """A membrane of tension C1 on springs k η + k₃ η³, with viscosity D0 η_t + D3 η_t³."""

    linear = False

    def __init__(self, density: float, thickness: float, tension: float, spring: float, cubic: float,
                 damping: float = 0.0, cubic_damping: float = 0.0):
        self.density, self.thickness, self.tension = density, thickness, tension
        self.spring, self.cubic, self.damping, self.cubic_damping = spring, cubic, damping, cubic_damping

    def linear_forms(self, space) -> LayerMatrices:
        """M = ρh ∫ηψ, C = D0 ∫ηψ, K = k ∫ηψ + C1 ∫η_zψ_z: the tangents at rest."""
        M = mass.assemble(space.basis).tocsr()
        K = (self.spring * M + self.tension * laplace.assemble(space.basis)).tocsr()
        return LayerMatrices((self.density * self.thickness * M).tocsr(), (self.damping * M).tocsr(), K)

    def forms(self, space) -> CubicSpringForms:
        m = self.linear_forms(space)
        return CubicSpringForms(m.mass, m.damping, m.stiffness, space.basis, self.cubic, self.cubic_damping)

    def long_wave_stiffness(self, radius=None) -> float:
        return self.spring


class LinearTwin(CubicSpringMembrane):
    """The same layer without its cubic terms, as linear forms (the linear step: one factorization per Δt)."""

    linear = True

    def forms(self, space) -> LayerMatrices:
        return self.linear_forms(space)


class WrongTangent(CubicSpringMembrane):
    """A mistake: the cubic spring's tangent without its factor 3."""

    def forms(self, space):
        good = super().forms(space)
        return _WrongTangentForms(good.mass, good.damping, good.stiffness, good.basis, good.cubic, good.cubic_damping)


@attrs.frozen(eq=False)
class _WrongTangentForms(CubicSpringForms):
    def tangent(self, d):
        return sp.csr_matrix(self.stiffness + self.cubic / 3.0 * self._cubic_tangent(d))


class WrongEnergy(CubicSpringMembrane):
    """A mistake: the stored energy ½k₃η⁴ where the force is k₃η³ (its gradient is 2k₃η³)."""

    def forms(self, space):
        good = super().forms(space)
        return _WrongEnergyForms(good.mass, good.damping, good.stiffness, good.basis, good.cubic, good.cubic_damping)


@attrs.frozen(eq=False)
class _WrongEnergyForms(CubicSpringForms):
    def elastic(self, d):
        return 2.0 * CubicSpringForms.elastic(self, d) - LayerMatrices.elastic(self, d)


class DeclaredLinear(CubicSpringMembrane):
    """A mistake: nonlinear forms from a layer that declares itself linear (the core would use K d)."""

    linear = True


PARAMS = (
    Param("density", "ρ₁", "g/cm³", gt=0.0, doc="density of the membrane"),
    Param("thickness", "h", "cm", gt=0.0, doc="thickness of the membrane"),
    Param("tension", "C1", "dyn/cm", ge=0.0, doc="tension"),
    Param("spring", "k", "dyn/cm³", ge=0.0, doc="linear spring stiffness (the hoop stiffness at rest)"),
    Param("cubic", "k₃", "dyn/cm⁵", ge=0.0, doc="cubic spring stiffness: the hoop force is k η + k₃ η³"),
    Param("damping", "D0", "dyn·s/cm³", default=0.0, ge=0.0, doc="linear viscosity"),
    Param("cubic_damping", "D3", "dyn·s³/cm⁵", default=0.0, ge=0.0, doc="cubic viscosity: D0 η_t + D3 η_t³"),
)
#: k₃ η² = k at η = 0.05 cm: the springs twice as stiff there as at rest
EXAMPLE = {"density": 1.1, "thickness": 0.1, "tension": 2.0e4, "spring": 2.0e5, "cubic": 8.0e7}


@hookimpl
def multilayer_layers():
    return [
        LayerPlugin("cubic-spring-membrane", CubicSpringMembrane, PARAMS,
                    "A membrane on stiffening springs k η + k₃ η³ (nonlinear, for the tests).", thin=True,
                    example=EXAMPLE),
        LayerPlugin("cubic-spring-twin", LinearTwin, PARAMS, "The same without its cubic terms, as linear forms.",
                    thin=True, example=EXAMPLE),
        LayerPlugin("broken-cubic-tangent", WrongTangent, PARAMS, "Broken on purpose: a tangent off by 3.",
                    thin=True, example=EXAMPLE),
        LayerPlugin("broken-cubic-energy", WrongEnergy, PARAMS, "Broken on purpose: W is not the force's energy.",
                    thin=True, example=EXAMPLE),
        LayerPlugin("broken-cubic-declared-linear", DeclaredLinear, PARAMS,
                    "Broken on purpose: nonlinear forms, declared linear.", thin=True, example=EXAMPLE),
    ]
