"""Koiter-family thin layers: the forms shared by ``wave-membrane`` and ``koiter-shell``.

A thin layer on the interface line r = R carries the radial displacement
η(t, z) of theory §1,

    ρ₁h η_tt + C0 η − C1 η_zz + C2 η_zzzz + D0 η_t − D1 η_tzz + D2 η_tzzzz = f,

with ends pinned (η = 0) and, where C2 or D2 ≠ 0, simply supported
(η_zz = 0).  Its forms of theory §6 A1 are

    mass     ρ₁h ∫ η ψ
    a₁(η,ψ)  ∫ C0 ηψ + C1 η_z ψ_z + C2 η_zz ψ_zz
    b₁(v,ψ)  ∫ D0 vψ + D1 v_z ψ_z + D2 v_zz ψ_zz

On C0 Lagrange elements η_zz is not a function, so ∫ η_zz ψ_zz is replaced
by a discrete bi-Laplacian (:func:`bilaplace`), which is symmetric positive
semi-definite: ½ a₁(η, η) stays an exact energy for the ledger of theory §7.
"""

from __future__ import annotations

import math

import attrs
import numpy as np
import scipy.sparse as sp
from skfem import BilinearForm, asm

from multilayer.geometry.spaces import LineSpace
from multilayer.plugin.records import Param
from multilayer.wall.layer import LayerMatrices, ThinLayer


@BilinearForm
def mass(eta, psi, w):
    """∫ η ψ (consistent mass, without the factor ρ₁h)."""
    return eta * psi


@BilinearForm
def laplace(eta, psi, w):
    """∫ η_z ψ_z (the C1 / D1 term)."""
    return eta.grad[0] * psi.grad[0]


def lumped(M: sp.spmatrix) -> np.ndarray:
    """Row sums of a mass matrix: the lumped (Gauss–Lobatto) mass, positive for 1D P1 and P2.

    >>> from multilayer.geometry.spaces import make_line_space
    >>> from multilayer_plugins.planar import Planar
    >>> lumped(asm(mass, make_line_space(1.0, 2, 2, 0.5, Planar()).basis)).round(4).tolist()
    [0.0833, 0.1667, 0.0833, 0.3333, 0.3333]
    """
    return np.asarray(M.sum(axis=1)).ravel()


def bilaplace(space: LineSpace, M: sp.spmatrix | None = None, Kz: sp.spmatrix | None = None) -> sp.csr_matrix:
    """The discrete bi-Laplacian (κ_h(η), κ_h(ψ))_L ≈ ∫ η_zz ψ_zz, simply supported.

    κ_h(η) is the discrete second derivative in V_h,0 (zero at the ends, so
    η_zz = 0 there): (κ_h, φ)_L = −(η_z, φ_z) for every φ in V_h,0, with
    (·,·)_L the lumped inner product.  With Kz the Laplacian stiffness, M_L
    the lumped mass and I the interior DOFs the form is the matrix

        B = Kz[I, :]ᵀ M_L[I]⁻¹ Kz[I, :],

    sparse (pentadiagonal for P1), symmetric and positive semi-definite.
    ``M`` and ``Kz`` may be passed when already assembled on ``space``.

    For P1 on a uniform mesh it is the classic five-point stencil
    (1, −4, 6, −4, 1)/h³ on the interior:

    >>> from multilayer.geometry.spaces import make_line_space
    >>> from multilayer_plugins.planar import Planar
    >>> B = bilaplace(make_line_space(6.0, 6, 1, 0.5, Planar())).toarray()
    >>> B[3, 1:6].round(12).tolist()
    [1.0, -4.0, 6.0, -4.0, 1.0]
    """
    M = asm(mass, space.basis) if M is None else M
    Kz = asm(laplace, space.basis) if Kz is None else Kz
    interior = np.setdiff1d(np.arange(space.ndofs), space.end_dofs)
    rows = sp.csr_matrix(Kz)[interior]
    B = rows.T @ sp.diags(1.0 / lumped(M)[interior]) @ rows
    # The sparse product sums (i, j) and (j, i) in different orders; the
    # energy ledger wants the form symmetric to the last bit.
    return sp.csr_matrix(0.5 * (B + B.T))


@attrs.frozen(eq=False)
class LineOperators:
    """The three matrices every Koiter-family form is a combination of.

    >>> from multilayer.geometry.spaces import make_line_space
    >>> from multilayer_plugins.planar import Planar
    >>> ops = LineOperators.assemble(make_line_space(1.0, 4, 1, 0.5, Planar()))
    >>> float(ops.mass.sum()), float(abs(ops.laplace.sum()) < 1e-12)
    (1.0, 1.0)
    """

    mass: sp.csr_matrix  #: ∫ η ψ
    laplace: sp.csr_matrix  #: ∫ η_z ψ_z
    bilaplace: sp.csr_matrix  #: discrete ∫ η_zz ψ_zz, see :func:`bilaplace`

    @classmethod
    def assemble(cls, space: LineSpace) -> LineOperators:
        M = asm(mass, space.basis).tocsr()
        Kz = asm(laplace, space.basis).tocsr()
        return cls(M, Kz, bilaplace(space, M, Kz))

    def combine(self, c0: float, c1: float, c2: float) -> sp.csr_matrix:
        """∫ c0 ηψ + c1 η_z ψ_z + c2 η_zz ψ_zz: a₁ with the Cᵢ, b₁ with the Dᵢ."""
        return sp.csr_matrix(c0 * self.mass + c1 * self.laplace + c2 * self.bilaplace)


def koiter_coefficients(
    thickness: float, young: float, poisson: float, radius: float
) -> tuple[float, float, float]:
    """(C0, C1, C2) of a linearly elastic cylindrical shell (theory §1).

    C0 = hE/(R²(1−σ²))·(1 + h²/(12R²)),  C1 = h³Eσ/(6R²(1−σ²)),  C2 = h³E/(12(1−σ²)).
    With the viscoelastic constants (E_v, σ_v) in place of (E, σ) the same
    formulas give (D0, D1, D2).

    >>> [round(c, 6) for c in koiter_coefficients(1.0, 12.0, 0.0, 1.0)]
    [13.0, 0.0, 1.0]
    """
    h, E, s, R = thickness, young, poisson, radius
    c0 = h * E / (R**2 * (1 - s**2)) * (1 + h**2 / (12 * R**2))
    c1 = h**3 * E * s / (6 * R**2 * (1 - s**2))
    c2 = h**3 * E / (12 * (1 - s**2))
    return c0, c1, c2


_positive = [attrs.validators.gt(0.0)]
_nonnegative = [attrs.validators.ge(0.0)]


@attrs.frozen
class KoiterFamilyLayer(ThinLayer):
    """A thin layer of the Koiter family, given by its coefficients (CGS units).

    ``wave-membrane`` is the case C0 = C2 = Dᵢ = 0; ``koiter-shell`` computes
    the coefficients from E, σ, R (:meth:`from_young_poisson`) or takes them
    as given.  C1 and D1 may be negative (σ < 0) as long as the symbol
    c0 + c1k² + c2k⁴ stays ≥ 0 for every wave number k, i.e. c1 ≥ −2√(c0 c2).

    >>> from multilayer.geometry.spaces import make_line_space
    >>> layer = KoiterFamilyLayer(density=1.1, thickness=0.1, C1=2.0)
    >>> from multilayer_plugins.planar import Planar
    >>> m = layer.forms(make_line_space(6.0, 3, 1, 0.5, Planar()))
    >>> round(float(m.mass.sum()), 12), m.stiffness.shape, layer.long_wave_stiffness()
    (0.66, (4, 4), 0.0)
    """

    density: float = attrs.field(converter=float, validator=_positive)  #: ρ₁ (g/cm³)
    thickness: float = attrs.field(converter=float, validator=_positive)  #: h (cm)
    C0: float = attrs.field(default=0.0, converter=float, validator=_nonnegative)  #: dyn/cm³
    C1: float = attrs.field(default=0.0, converter=float)  #: dyn/cm
    C2: float = attrs.field(default=0.0, converter=float, validator=_nonnegative)  #: dyn·cm
    D0: float = attrs.field(default=0.0, converter=float, validator=_nonnegative)  #: dyn·s/cm³
    D1: float = attrs.field(default=0.0, converter=float)  #: dyn·s/cm
    D2: float = attrs.field(default=0.0, converter=float, validator=_nonnegative)  #: dyn·s·cm

    def __attrs_post_init__(self) -> None:
        for c0, c1, c2 in (("C0", "C1", "C2"), ("D0", "D1", "D2")):
            lo = -2.0 * math.sqrt(getattr(self, c0) * getattr(self, c2))
            if getattr(self, c1) < lo:
                raise ValueError(
                    f"{c1} = {getattr(self, c1):g} makes {c0} + {c1}·k² + {c2}·k⁴ negative "
                    f"for some wave number k; expected {c1} >= -2·sqrt({c0}·{c2}) = {lo:g}"
                )

    @classmethod
    def from_young_poisson(
        cls,
        density: float,
        thickness: float,
        young: float,
        poisson: float,
        radius: float,
        viscous_young: float = 0.0,
        viscous_poisson: float | None = None,
    ) -> KoiterFamilyLayer:
        """The (visco)elastic cylindrical shell of radius R (theory §1).

        young E (dyn/cm²), poisson σ in (−1, 0.5), radius R (cm), viscous_young
        E_v (dyn·s/cm²), viscous_poisson σ_v (defaults to σ).

        >>> s = KoiterFamilyLayer.from_young_poisson(1.0, 1.0, 12.0, 0.0, 1.0)
        >>> s.C0, s.C2, s.D0
        (13.0, 1.0, 0.0)
        """
        for name, value in (("poisson", poisson), ("viscous_poisson", viscous_poisson)):
            if value is not None and not -1.0 < value < 0.5:
                raise ValueError(f"{name} = {value!r}; expected > -1 and < 0.5")
        if young <= 0 or radius <= 0 or viscous_young < 0:
            raise ValueError(
                f"young = {young!r}, radius = {radius!r}, viscous_young = {viscous_young!r}; "
                "expected young > 0, radius > 0, viscous_young >= 0"
            )
        C = koiter_coefficients(thickness, young, poisson, radius)
        sv = poisson if viscous_poisson is None else viscous_poisson
        D = koiter_coefficients(thickness, viscous_young, sv, radius)
        return cls(density, thickness, *C, *D)

    def forms(self, space: LineSpace) -> LayerMatrices:
        """ρ₁h ∫ηψ, b₁ and a₁ on ``space``, in its own DOF numbering (CSR)."""
        ops = LineOperators.assemble(space)
        return LayerMatrices(
            mass=sp.csr_matrix(self.density * self.thickness * ops.mass),
            damping=ops.combine(self.D0, self.D1, self.D2),  # b₁
            stiffness=ops.combine(self.C0, self.C1, self.C2),  # a₁
        )

    def long_wave_stiffness(self, radius: float | None = None) -> float:
        """C0 (dyn/cm³); the coefficients are given, so ``radius`` is not needed."""
        return self.C0


def mass_params(what: str) -> tuple[Param, Param]:
    """The parameters of ρ₁h every thin layer has: ``density`` and ``thickness`` of ``what``."""
    return (Param("density", "ρ₁", "g/cm³", gt=0.0, doc=f"density of the {what}"),
            Param("thickness", "h", "cm", gt=0.0, doc=f"thickness of the {what}"))
