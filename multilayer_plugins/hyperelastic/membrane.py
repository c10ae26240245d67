"""``neo-hookean-membrane``, ``hgo-membrane``: a thin hyperelastic wall on a line, its hoop tension from a strain energy.

The layer is the thin-walled limit of an incompressible hyperelastic tube
(:mod:`multilayer_plugins.hyperelastic.membrane_laws`): a wall of thickness h (at rest,
unstretched) on the line r = R, whose point at z moves to r = R + η(z).
Its stretches are

    λθ = (R + η)/R   around,     λz = λz0 √(1 + η_z²)   along (the meridian's line element),

λz0 the axial prestretch (the line's length at rest over the wall's own),
and its stored energy, per unit area of the line at rest (the geometry's
measure dA: 2πR dz in a tube, dz per unit depth in a planar channel), is

    W(η) = ∫ (h/λz0) [Ψ(λθ, λz) − Ψ(1, λz0)] dA

(the wall's own area is dA/λz0; the constant makes W = 0 at rest).  The
internal force is W's gradient and the tangent its Hessian, assembled from
η and η_z at the line's quadrature points (:class:`MembraneForms`):

    f(ψ) = ∫ (h/λz0) [Ψ_θ ψ/R + Ψ_z λz' ψ_z] dA,       λz' = ∂λz/∂η_z = λz0 η_z/√(1 + η_z²),

so the force is the exact gradient of the discrete W and Newton's
iteration converges quadratically.  The mass is ρh/λz0 ∫ηψ dA; an optional
linear viscosity D0 ∫vψ + D1 ∫v_zψ_z (the Koiter shell's b₁).

**At rest** the tangent is the linear thin layer

    C0 = h Ψ_θθ(1, λz0)/(λz0 R²),    C1 = h Ψ_z(1, λz0)

(:meth:`HyperelasticMembrane.rest_coefficients`): without prestretch C1 = 0
and C0 = 4hc/R² for the neo-Hookean law, the membrane part of Koiter's C0
with E = 3c, σ = ½; the HGO fibres add 8 k1 cos⁴β h/R² (their loading
stiffness; they bear nothing in compression).  With λz0 > 1 the wall is
under an axial tension C1 and, at rest, a hoop tension that pulls the line
inward: f(0) = h Ψ_θ(1, λz0)/(λz0 R) ∫ψ dA ≠ 0, held by a lumen pressure
(``[initial] pressure``).

**Inflation.** A uniform η under a pressure p on the moved lumen (the
fluid's force per unit area at rest is p ((R + η)/R)ᵏ, k = 1 in a tube,
0 planar) is in equilibrium when

    p λθᵏ = h Ψ_θ(λθ, λz0)/(λz0 R)       (:func:`inflation_pressure`)

— in a tube Laplace's law p = σθθ t/r with σθθ = λθΨ_θ, the thickness
t = h/(λθλz0) and the radius r = Rλθ.  In a planar channel the "hoop"
direction is out of the plane: λθ = (R + η)/R with R the channel's
half-width is a spring whose stiffness follows the law, as the Koiter
family's C0 = hE/(R²(1−σ²)) is in a planar channel.
"""

from __future__ import annotations

from typing import Any, ClassVar

import attrs
import numpy as np
import scipy.sparse as sp
import skfem

from multilayer.geometry.spaces import LineSpace
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import LayerPlugin, Param
from multilayer.wall.layer import NonlinearForms, ThinLayer
from multilayer_plugins.hyperelastic.membrane_laws import MembraneEnergy, MembraneLaw
from multilayer_plugins.thin_shell import LineOperators, mass_params


@skfem.Functional
def stored_energy(w):
    """∫ e: the energy density e at the quadrature points."""
    return w["e"]


@skfem.LinearForm
def internal_force(psi, w):
    """∫ a ψ + b ψ_z: the hoop part a = (h/λz0) Ψ_θ/R, the axial part b = (h/λz0) Ψ_z λz'."""
    return w["a"] * psi + w["b"] * psi.grad[0]


@skfem.BilinearForm
def internal_tangent(u, psi, w):
    """∫ A uψ + B (uψ_z + u_zψ) + C u_zψ_z: the derivative of :func:`internal_force` (symmetric)."""
    return w["A"] * u * psi + w["B"] * (u * psi.grad[0] + u.grad[0] * psi) + w["C"] * u.grad[0] * psi.grad[0]


@skfem.BilinearForm
def weighted_mass(u, psi, w):
    """∫ m u ψ: a mass per unit area m at the quadrature points."""
    return w["weight"] * u * psi


@attrs.frozen(eq=False)
class MembraneForms(NonlinearForms):
    """The membrane's forms on a line: W, its gradient and Hessian from η, η_z at the quadrature points."""

    basis: Any  #: the line's basis (its measure is the geometry's)
    law: MembraneLaw
    thickness: float  #: h (cm)
    radius: float  #: R (cm)
    axial_stretch: float  #: λz0
    #: on a reference off the line (:meth:`HyperelasticMembrane.forms_on_reference`), at the quadrature points:
    #: R/(R + D) (the hoop stretch's factor), √(1 + D_z²) (the reference meridian's length element), and
    #: ((R + D)/R)ᵏ √(1 + D_z²) (the reference's area over the line's); 1 on the line itself
    hoop: Any = 1.0
    meridian: Any = 1.0
    area: Any = 1.0

    def _state(self, d: np.ndarray) -> tuple[MembraneEnergy, np.ndarray, np.ndarray, np.ndarray]:
        """Ψ and its derivatives at the stretches of ``d``, with λz' and λz'' = ∂²λz/∂η_z² = λz0/(1 + η_z²)^(3/2)
        (over the reference's meridian element), and the scale h/λz0 of Ψ per unit area of the line."""
        eta = self.basis.interpolate(d)
        slope = eta.grad[0]
        root = np.sqrt(1.0 + slope * slope)
        lz0 = self.axial_stretch
        psi = self.law.energy((1.0 + np.asarray(eta) / self.radius) * self.hoop, lz0 * root / self.meridian)
        return (psi, lz0 * slope / root / self.meridian, lz0 / root**3 / self.meridian,
                self.thickness / lz0 * self.area)

    def elastic(self, d: np.ndarray) -> float:
        """W(d) = ∫ (h/λz0)(Ψ(λθ, λz) − Ψ(1, λz0)) dA."""
        psi, _, _, scale = self._state(d)
        rest = self.law.energy(np.ones(1), np.full(1, self.axial_stretch)).value[0]  # (the reference is at rest)
        return float(stored_energy.assemble(self.basis, e=scale * (psi.value - rest)))

    def force(self, d: np.ndarray) -> np.ndarray:
        """∇W(d)."""
        psi, slope, _, scale = self._state(d)
        return internal_force.assemble(self.basis, a=scale * psi.d_theta * self.hoop / self.radius,
                                       b=scale * psi.d_z * slope)

    def tangent(self, d: np.ndarray) -> sp.csr_matrix:
        """∇²W(d)."""
        psi, slope, curvature, scale = self._state(d)
        R = self.radius / self.hoop  # the reference's radius R + D
        return sp.csr_matrix(internal_tangent.assemble(
            self.basis, A=scale * psi.d_theta_theta / R**2, B=scale * psi.d_theta_z * slope / R,
            C=scale * (psi.d_z_z * slope * slope + psi.d_z * curvature)))


@attrs.frozen
class HyperelasticMembrane(ThinLayer):
    """A thin incompressible wall of the law ``law`` on the line it is placed on (its radius is the line's).

    >>> from multilayer.geometry.spaces import make_line_space
    >>> from multilayer_plugins.planar import Planar
    >>> layer = HyperelasticMembrane(MembraneLaw(c=1e6), density=1.1, thickness=0.01)
    >>> forms = layer.forms(make_line_space(6.0, 4, 1, 0.5, Planar()))
    >>> layer.long_wave_stiffness(0.5) == 4 * 0.01 * 1e6 / 0.5**2, forms.elastic(np.zeros(5))
    (True, 0.0)
    """

    linear: ClassVar[bool] = False

    law: MembraneLaw
    density: float = attrs.field(converter=float, validator=attrs.validators.gt(0.0))  #: ρ₁ (g/cm³)
    thickness: float = attrs.field(converter=float, validator=attrs.validators.gt(0.0))  #: h at rest (cm)
    #: λz0, the axial prestretch
    axial_stretch: float = attrs.field(default=1.0, converter=float, validator=attrs.validators.gt(0.0))
    D0: float = attrs.field(default=0.0, converter=float, validator=attrs.validators.ge(0.0))  #: dyn·s/cm³
    D1: float = attrs.field(default=0.0, converter=float, validator=attrs.validators.ge(0.0))  #: dyn·s/cm

    def forms(self, space: LineSpace) -> MembraneForms:
        """Mass ρh/λz0 ∫ηψ, damping D0 ∫vψ + D1 ∫v_zψ_z, and the stiffness: the tangent at rest."""
        ops = LineOperators.assemble(space)
        rest = MembraneForms(ops.mass, ops.mass, ops.mass, space.basis, self.law, self.thickness, space.radius,
                             self.axial_stretch)
        return attrs.evolve(rest, mass=sp.csr_matrix(self.density * self.thickness / self.axial_stretch * ops.mass),
                            damping=ops.combine(self.D0, self.D1, 0.0), stiffness=rest.tangent(np.zeros(space.ndofs)))

    def forms_on_reference(self, space: LineSpace, reference: np.ndarray) -> MembraneForms:
        """The forms of the membrane whose unloaded line is r = R + D(z) (``reference`` = D on the line), its
        points at their z: the stretches λθ = (R + η)/(R + D) and λz = λz0 √(1 + η_z²)/√(1 + D_z²) (the axial
        prestretch λz0 as given), Ψ per unit area of that line, ((R + D)/R)ᵏ √(1 + D_z²) of the mesh's; the
        mass ρh/λz0 over it too.  At the pinned ends (held in their place) D is the nearest other point's: the
        reference line runs on to the ends as it does inside, rather than folding back to the mesh's place in
        the end cell."""
        R = space.radius
        D = space.basis.interpolate(_ends_as_neighbours(space, reference))
        base = R + np.asarray(D)
        if not np.all(base > 0.0):
            raise ValueError("the stress-free line closes the channel (R + D ≤ 0)")
        meridian = np.sqrt(1.0 + D.grad[0] ** 2)
        area = (base / R) ** space.geometry.radial_power * meridian
        rest = self.forms(space)
        ref = attrs.evolve(rest, hoop=R / base, meridian=meridian, area=area)
        mass = sp.csr_matrix(weighted_mass.assemble(space.basis, weight=self.density * self.thickness
                                                     / self.axial_stretch * area))
        return attrs.evolve(ref, mass=mass, stiffness=ref.tangent(np.zeros(space.ndofs)))

    def rest_coefficients(self, radius: float) -> tuple[float, float]:
        """(C0, C1) of the linear thin layer the membrane is at rest on a line of radius ``radius`` (cm):
        h Ψ_θθ(1, λz0)/(λz0 R²) (dyn/cm³) and h Ψ_z(1, λz0) (dyn/cm)."""
        psi = self.law.energy(np.ones(1), np.full(1, self.axial_stretch))
        h, lz0 = self.thickness, self.axial_stretch
        return float(h * psi.d_theta_theta[0] / (lz0 * radius**2)), float(h * psi.d_z[0])

    def long_wave_stiffness(self, radius: float | None = None) -> float:
        """C0 (dyn/cm³): the hoop stiffness at rest on a line of radius ``radius`` (cm)."""
        if radius is None:
            raise ValueError("the membrane takes its line's radius: pass radius= to long_wave_stiffness")
        return self.rest_coefficients(radius)[0]


def _ends_as_neighbours(space: LineSpace, reference: np.ndarray) -> np.ndarray:
    """``reference`` (on the line) with its value at each end DOF replaced by the nearest other DOF's."""
    D = np.array(reference, dtype=float)
    ends = space.end_dofs
    inner = np.setdiff1d(np.arange(space.ndofs), ends)
    if inner.size:
        z = space.z
        D[ends] = D[inner[np.argmin(np.abs(z[inner][None, :] - z[ends][:, None]), axis=1)]]
    return D


def inflation_pressure(layer: HyperelasticMembrane, radius: float, stretch_theta: float, radial_power: int = 1) -> float:
    """p (dyn/cm²) that holds the membrane inflated uniformly to λθ on a line of radius R (cm): the closed form
    p λθᵏ = h Ψ_θ(λθ, λz0)/(λz0 R), k = 1 in a tube (Laplace's law), 0 in a planar channel.

    The neo-Hookean tube's p = (hc/(R λz0)) (1 − λθ⁻⁴ λz0⁻²):

    >>> layer = HyperelasticMembrane(MembraneLaw(c=3.0), density=1.0, thickness=0.1, axial_stretch=1.2)
    >>> p = inflation_pressure(layer, 0.5, 1.3)
    >>> abs(p - 0.1 * 3.0 / (0.5 * 1.2) * (1 - 1.3**-4 * 1.2**-2)) < 1e-15
    True
    """
    psi = layer.law.energy(np.array([stretch_theta]), np.array([layer.axial_stretch]))
    return float(layer.thickness * psi.d_theta[0] / (layer.axial_stretch * radius * stretch_theta**radial_power))


def neo_hookean_membrane(density: float, thickness: float, c: float, axial_stretch: float = 1.0, D0: float = 0.0,
                         D1: float = 0.0) -> HyperelasticMembrane:
    """The layer of a ``neo-hookean-membrane`` case entry."""
    return HyperelasticMembrane(MembraneLaw(c), density, thickness, axial_stretch, D0, D1)


def hgo_membrane(density: float, thickness: float, c: float, k1: float, k2: float, angle: float,
                 axial_stretch: float = 1.0, D0: float = 0.0, D1: float = 0.0) -> HyperelasticMembrane:
    """The layer of an ``hgo-membrane`` case entry."""
    return HyperelasticMembrane(MembraneLaw(c, k1, k2, angle), density, thickness, axial_stretch, D0, D1)


_C = Param("c", "c", "dyn/cm²", gt=0.0, doc="shear modulus of the matrix: Ψ = c/2 (I1 − 3) + fibres")
_COMMON = (
    Param("axial_stretch", "λz0", "1", default=1.0, gt=0.0,
          doc="axial prestretch: the line's length at rest over the wall's own (≠ 1: a hoop tension at rest)"),
    Param("D0", "D0", "dyn·s/cm³", default=0.0, ge=0.0, doc="viscosity: the damping D0 ∫vψ (Koiter's D0)"),
    Param("D1", "D1", "dyn·s/cm", default=0.0, ge=0.0, doc="viscosity: the damping D1 ∫v_zψ_z (Koiter's D1)"),
)
_FIBRES = (
    Param("k1", "k1", "dyn/cm²", ge=0.0, doc="stiffness of the fibres: k1/(2k2)(exp(k2(I4 − 1)²) − 1) in extension"),
    Param("k2", "k2", "1", ge=0.0, doc="exponential stiffening of the fibres (0: quadratic, k1(I4 − 1)²/2)"),
    Param("angle", "β", "deg", ge=0.0, le=90.0, doc="angle of the two fibre families to the circumferential direction"),
)


@hookimpl
def multilayer_layers() -> list[LayerPlugin]:
    """The ``neo-hookean-membrane`` and ``hgo-membrane`` layers."""
    return [
        LayerPlugin(
            name="neo-hookean-membrane",
            factory=neo_hookean_membrane,
            params=(*mass_params("membrane at rest"), _C, *_COMMON),
            doc="Thin incompressible neo-Hookean wall: hoop and axial tension from Ψ = c/2 (I1 − 3), ends pinned.",
            thin=True,
            example={"density": 1.06, "thickness": 0.005, "c": 6.7e5},
        ),
        LayerPlugin(
            name="hgo-membrane",
            factory=hgo_membrane,
            params=(*mass_params("membrane at rest"), _C, *_FIBRES, *_COMMON),
            doc="Thin incompressible HGO wall: a neo-Hookean matrix with two fibre families at ±β, ends pinned.",
            thin=True,
            example={"density": 1.06, "thickness": 0.005, "c": 3.0e5, "k1": 2.4e5, "k2": 0.8, "angle": 40.0},
        ),
    ]
