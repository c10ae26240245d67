"""``neo-hookean`` and ``hgo``: thick bands of nearly incompressible hyperelastic materials (theory §1,
"Hyperelastic bands").

The stored energy of the band, total Lagrangian on its reference configuration (:mod:`.kinematics`), is

    W(d) = Σ_q w_q Ψ_iso(F_q) + Σ_g V_g U(J̄_g),      J̄_g = Σ_{q∈g} w_q J_q / V_g,   V_g = Σ_{q∈g} w_q,

Ψ_iso the isochoric energy of the law (:mod:`.laws`: neo-Hookean c/2 (Ī₁ − 3), HGO adding two fibre families),
U(J) = κ/2 (J − 1)² taken at the dilatation J̄ averaged over each group g (mean dilatation: a three-field
Hu–Washizu form with the pressure and dilatation constant per group, condensed).  W is a function of d, so its
force is its exact gradient and its tangent its exact Hessian:

    f(d) = Σ_q w_q P_iso : ∂F/∂d + Σ_q m_q ∂J_q/∂d,                 m_q = Σ_g S_gq U'(J̄_g),
    K_T(d) = Σ_q ∂F/∂dᵀ (w_q A_iso + m_q ∂²J/∂F²) ∂F/∂d + Gᵀ diag(U''(J̄_g)/V_g) G,   G = S ∂J/∂d,

S the groups' weights.  The mass is ρ ∫ u·v over the reference volume; the band has no damping.  At rest
(λ_z = 1) the tangent is linear elasticity with μ = c and, for the dilatation, κ times the group means
(λ = κ − 2c/3 where the dilatation is constant over a group).
"""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np
import scipy.sparse as sp

from multilayer.geometry.spaces import BandSpace
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import LayerPlugin, Param
from multilayer.wall.layer import NonlinearForms, ThickLayer
from multilayer_plugins.hyperelastic.kinematics import BandKinematics
from multilayer_plugins.hyperelastic.laws import Isochoric, Strain, Volumetric
from multilayer_plugins.linear_elastic import CONDITIONS, band_conditions, mass


@attrs.frozen(eq=False)
class HyperelasticForms(NonlinearForms):
    """The band's mass, its tangent at rest, and its energy, force and tangent at any displacement."""

    kinematics: BandKinematics
    law: Isochoric
    volumetric: Volumetric
    #: the last displacements' states and stress (:meth:`_state`, :meth:`_stress`): a Newton correction's residual,
    #: its terms' size and the tangent evaluate them at the same few d
    _last: dict = attrs.field(factory=dict, init=False, repr=False)

    def _state(self, d: np.ndarray) -> tuple[Strain, np.ndarray, np.ndarray]:
        """The strain at the points, each group's J̄ − 1, and the groups' volumes V (the last three d's kept)."""
        kept = self._last.setdefault("states", [])
        for at, state in kept:
            if np.array_equal(at, d):
                return state
        kin = self.kinematics
        strain = Strain.of(kin.gradient(d), self.law.beta)
        V = kin.volumes
        state = strain, (kin.groups @ strain.J1.ravel()) / V, V
        kept.insert(0, (np.array(d, copy=True), state))
        del kept[3:]  # a Crank–Nicolson correction's three: d^{n+1}, the midpoint, dⁿ
        return state

    def _pressure(self, Jbar1: np.ndarray) -> np.ndarray:
        """m_q = Σ_g S_gq U'(J̄_g): each point's weighted share of the groups' pressures."""
        _, U1, _ = self.volumetric.derivatives(Jbar1)
        return (self.kinematics.groups_t @ U1).reshape(self.kinematics.weights.shape)

    def elastic(self, d: np.ndarray) -> float:
        """W(d) = Σ_q w_q Ψ_iso + Σ_g V_g U(J̄_g)."""
        strain, Jbar1, V = self._state(d)
        U, _, _ = self.volumetric.derivatives(Jbar1)
        return float(np.sum(self.kinematics.weights * self.law.energy(strain)) + V @ U)

    def _stress(self, d: np.ndarray) -> np.ndarray:
        """The weighted first derivatives of W at the points: w_q P_iso + m_q ∂J/∂F (5, E, Q) (the last d's kept:
        the force and its size are taken at one d)."""
        last = self._last.get("stress")
        if last is not None and np.array_equal(last[0], d):
            return last[1]
        strain, Jbar1, _ = self._state(d)
        stress = self.kinematics.weights * self.law.stress(strain) + self._pressure(Jbar1) * strain.cofactor
        self._last["stress"] = (np.array(d, copy=True), stress)
        return stress

    def _local_forces(self, d: np.ndarray) -> np.ndarray:
        """The elements' forces (elements, local DOFs) at ``d`` (the last d's kept: a residual takes the force and
        its size at one d)."""
        last = self._last.get("local")
        if last is not None and np.array_equal(last[0], d):
            return last[1]
        local = self.kinematics.local_vector(self._stress(d))
        self._last["local"] = (np.array(d, copy=True), local)
        return local

    def force(self, d: np.ndarray) -> np.ndarray:
        """∇W(d)."""
        return self.kinematics.scatter(self._local_forces(d))

    def force_size(self, d: np.ndarray) -> np.ndarray:
        """The magnitudes of the elements' forces, summed: a prestressed band's (λ_z ≠ 1) cancel at every DOF."""
        return self.kinematics.scatter(np.abs(self._local_forces(d)))

    def tangent(self, d: np.ndarray) -> sp.csr_matrix:
        """∇²W(d)."""
        kin = self.kinematics
        strain, Jbar1, V = self._state(d)
        _, _, U2 = self.volumetric.derivatives(Jbar1)
        _, ddJ = strain.derivatives(self.law.beta)
        A = kin.weights * self.law.tangent(strain) + self._pressure(Jbar1) * ddJ[2]
        local = kin.local_matrix(A)
        if kin.per_element:  # G_g is element g's own: its rank-one term is an element matrix
            G = kin.local_vector(kin.weights * strain.cofactor)
            return kin.assemble(local + (U2 / V)[:, None, None] * G[:, :, None] * G[:, None, :])
        G = kin.groups @ kin.rows(strain.cofactor)  # ∂(V_g J̄_g)/∂d, one row per group
        return (kin.assemble(local) + G.T @ sp.diags(U2 / V) @ G).tocsr()


@attrs.frozen
class HyperelasticBand(ThickLayer):
    """A thick band of a nearly incompressible hyperelastic material.  Units: density g/cm³, thickness cm,
    moduli dyn/cm²; ``law`` the isochoric energy, ``bulk`` κ; ``axial_stretch`` λ_z (:mod:`.kinematics`);
    ``ends``, ``faces``, ``outer`` as ``linear-elastic``'s."""

    linear: ClassVar[bool] = False

    density: float
    thickness: float
    law: Isochoric
    bulk: float
    axial_stretch: float = 1.0
    ends: str = "clamped"
    faces: str = "free"
    outer: str = "free"

    def forms(self, space: BandSpace) -> HyperelasticForms:
        kin = BandKinematics.build(space.basis, space.geometry.radial_power, self.axial_stretch, space.order)
        M = (mass.assemble(space.basis, density=self.density / self.axial_stretch)).tocsr()
        return self._forms(M, kin)

    def forms_on_reference(self, space: BandSpace, reference: np.ndarray) -> HyperelasticForms:
        """The forms of the band whose reference (unloaded, before λ_z) is the mesh moved by ``reference``
        (:meth:`.BandKinematics.referenced`); its mass ρ ∫ u·v over the reference volume."""
        kin = BandKinematics.build(space.basis, space.geometry.radial_power, self.axial_stretch, space.order)
        kin = kin.referenced(np.asarray(reference, dtype=float))
        M = (mass.assemble(space.basis, density=self.density * kin.weights / np.asarray(space.basis.dx))).tocsr()
        return self._forms(M, kin)

    def _forms(self, M: sp.csr_matrix, kin: BandKinematics) -> HyperelasticForms:
        """The forms of the mass ``M`` and the kinematics ``kin``, their stiffness the tangent at d = 0."""
        forms = HyperelasticForms(M, sp.csr_matrix(M.shape), sp.csr_matrix(M.shape), kin, self.law,
                                  Volumetric(self.bulk))
        return attrs.evolve(forms, stiffness=forms.tangent(np.zeros(kin.ndofs)))

    def essential_dofs(self, space: BandSpace) -> np.ndarray:
        return band_conditions(space, self.ends, self.faces, self.outer)


def neo_hookean(density, thickness, shear_modulus, bulk_modulus, axial_stretch=1.0, ends="clamped", faces="free",
                outer="free") -> HyperelasticBand:
    return HyperelasticBand(density, thickness, Isochoric(shear_modulus), bulk_modulus, axial_stretch, ends, faces,
                            outer)


def hgo(density, thickness, shear_modulus, bulk_modulus, fibre_modulus, fibre_exponent, fibre_angle,
        axial_stretch=1.0, ends="clamped", faces="free", outer="free") -> HyperelasticBand:
    law = Isochoric(shear_modulus, fibre_modulus, fibre_exponent, np.deg2rad(fibre_angle))
    return HyperelasticBand(density, thickness, law, bulk_modulus, axial_stretch, ends, faces, outer)


MATRIX = (
    Param("density", "ρ₂", "g/cm³", gt=0.0, doc="mass density of the band (unloaded)"),
    Param("thickness", "H", "cm", gt=0.0, doc="radial thickness of the band (unloaded)"),
    Param("shear_modulus", "c", "dyn/cm²", gt=0.0, doc="the matrix's modulus c: Ψ = c/2 (Ī₁ − 3); μ = c at small strain"),
    Param("bulk_modulus", "κ", "dyn/cm²", gt=0.0,
          doc="bulk modulus κ of U(J) = κ/2 (J − 1)²: nearly incompressible for κ ≫ the stiffest modulus reached"),
)
FIBRES = (
    Param("fibre_modulus", "k₁", "dyn/cm²", gt=0.0, doc="the fibres' modulus k₁"),
    Param("fibre_exponent", "k₂", "1", gt=0.0, doc="the fibres' stiffening k₂: k₁/(2k₂) (exp(k₂ (Ī₄ − 1)²) − 1)"),
    Param("fibre_angle", "β", "deg", ge=0.0, le=90.0, doc="angle β of the two fibre families to θ, at ±β toward z"),
)
KINEMATICS = (
    Param("axial_stretch", "λ_z", "1", 1.0, gt=0.0,
          doc="the band held at λ_z times its unloaded length (the mesh's z); r of the mesh is unloaded"),
    *CONDITIONS,
)
#: the rabbit carotid's media (Holzapfel, Gasser & Ogden 2000) in CGS, κ = 10³ c
MEDIA = {"density": 1.1, "thickness": 0.026, "shear_modulus": 3.0e4, "bulk_modulus": 3.0e7,
         "fibre_modulus": 2.3632e4, "fibre_exponent": 0.8393, "fibre_angle": 29.0}


@hookimpl
def multilayer_layers():
    return [
        LayerPlugin("neo-hookean", neo_hookean, MATRIX + KINEMATICS, thin=False,
                    doc="Thick band, nearly incompressible neo-Hookean, total Lagrangian with mean dilatation.",
                    example={k: MEDIA[k] for k in ("density", "thickness", "shear_modulus", "bulk_modulus")}),
        LayerPlugin("hgo", hgo, MATRIX + FIBRES + KINEMATICS, thin=False,
                    doc="Thick band, nearly incompressible Holzapfel–Gasser–Ogden (matrix and two fibre families).",
                    example=MEDIA),
    ]
