"""Strain energies of nearly incompressible hyperelastic walls, in invariants, with their first and second
derivatives with respect to the deformation gradient (docs/theory-wall.md, "Hyperelastic bands").

The wall's deformation gradient, on the meridian plane (z, r) with the hoop direction θ, has five entries

    F = I + H = [[F_zZ, F_zR, 0], [F_rZ, F_rR, 0], [0, 0, F_θΘ]],

held as vectors ``(zZ, zR, rZ, rR, θΘ)`` (first axis of every array; the others are the elements and
quadrature points).  The energy per unit reference volume is split

    Ψ = Ψ_iso(Ī₁, Ī₄, Ī₆) + U(J),   Ī = J^(−2/3) I,   J = det F,

with the neo-Hookean matrix c/2 (Ī₁ − 3) and, for HGO, two fibre families at ±β to θ in the (θ, Z) plane,
k₁/(2k₂) Σ_{i=4,6} (exp(k₂ (Ī_i − 1)²) − 1), active only where Ī_i > 1 (fibres do not bear compression).
With a = cos β e_θ ± sin β e_Z, I₄ = I₆ = sin²β (F_zZ² + F_rZ²) + cos²β F_θΘ²: the two families stretch alike
(F has no (θ, Z) shear), so their energies add as one term of twice the weight.  U(J) = κ/2 (J − 1)² is the
volumetric energy; the band takes it at the dilatation averaged over a group of quadrature points (mean
dilatation), so it is kept apart (:class:`Volumetric`).

The tangent follows by the chain rule through x = (I₁, I₄, J):

    A = ∂²Ψ_iso/∂F² = Σ_kl ψ_kl ∂x_k/∂F ⊗ ∂x_l/∂F + Σ_k ψ_k ∂²x_k/∂F²,

ψ_k, ψ_kl the derivatives of Ψ_iso(I₁, I₄, J) in x.  The energy and the stress P = ∂Ψ_iso/∂F are evaluated
from H without the cancellation of their first-order terms (:class:`Strain`): at a strain ε the sum
Σ_k ψ_k ∂x_k/∂F adds terms of size c to a stress of size cε, and would leave the force a round-off error of
10⁻¹⁶/ε of its size, too much for a Newton iteration to reach 10⁻¹¹ at the small strains of a pulse.
"""

from __future__ import annotations

import attrs
import numpy as np

from multilayer_plugins.hyperelastic.membrane_laws import Energy, hgo_fibre


def transpose(M: np.ndarray) -> np.ndarray:
    """Mᵀ of a tensor held as (zZ, zR, rZ, rR, θΘ)."""
    return M[[0, 2, 1, 3, 4]]


@attrs.frozen(eq=False)
class Strain:
    """The kinematic quantities of the laws at H = F − I, each accurate to round-off relative to its own size.

    >>> s = Strain.of(np.array([0.0, 0.0, 0.0, 0.0, 1.0]), 0.0)   # F = diag(1, 1, 2)
    >>> [float(x) for x in (s.I1, s.I4, s.J, s.J1, s.Q)]
    [6.0, 4.0, 2.0, 1.0, 1.0]
    """

    H: np.ndarray  #: F − I (5, ...)
    F: np.ndarray  #: F (5, ...)
    I1: np.ndarray  #: tr C
    I1m3: np.ndarray  #: I₁ − 3
    I4: np.ndarray  #: the fibres' a·Ca
    I4m1: np.ndarray  #: I₄ − 1
    J: np.ndarray  #: det F
    J1: np.ndarray  #: J − 1
    Q: np.ndarray  #: I₁ − 3 − 2(J − 1), of second order in H
    cofactor: np.ndarray  #: ∂J/∂F = J F⁻ᵀ (5, ...)

    @classmethod
    def of(cls, H: np.ndarray, beta: float) -> Strain:
        """The quantities at ``H``, fibres at ``beta`` (radians) to θ."""
        zZ, zR, rZ, rR, t = H
        F = H.copy()
        F[[0, 3, 4]] += 1.0
        s2, c2 = np.sin(beta) ** 2, np.cos(beta) ** 2
        I1m3 = 2.0 * (zZ + rR + t) + np.sum(H**2, axis=0)
        det = zZ * rR - zR * rZ  # det(F₂) − 1 − tr h of the (z, r) block
        J1 = (zZ + rR + det) * (1.0 + t) + t
        # |h|² − 2 det h + t² − 2t tr h − 2t det h: I₁ − 3 − 2(J − 1) with the first-order terms taken out
        Q = (zZ - rR) ** 2 + (zR + rZ) ** 2 + t**2 - 2.0 * t * (zZ + rR) - 2.0 * t * det
        I4m1 = s2 * (2.0 * zZ + zZ**2 + rZ**2) + c2 * (2.0 * t + t**2)
        cof = np.stack([F[3] * F[4], -F[2] * F[4], -F[1] * F[4], F[0] * F[4], F[0] * F[3] - F[1] * F[2]])
        return cls(H, F, I1m3 + 3.0, I1m3, I4m1 + 1.0, I4m1, J1 + 1.0, J1, Q, cof)

    def derivatives(self, beta: float) -> tuple[np.ndarray, np.ndarray]:
        """∂x/∂F (3, 5, ...) and ∂²x/∂F² (3, 5, 5, ...) for x = (I₁, I₄, J)."""
        F = self.F
        s2, c2 = np.sin(beta) ** 2, np.cos(beta) ** 2
        d = np.empty((3,) + F.shape)
        d[0] = 2.0 * F
        d[1] = 2.0 * np.stack([s2 * F[0], 0.0 * F[1], s2 * F[2], 0.0 * F[3], c2 * F[4]])
        d[2] = self.cofactor
        dd = np.zeros((3, 5, 5) + F.shape[1:])
        for i in range(5):
            dd[0, i, i] = 2.0
        for i, w in ((0, s2), (2, s2), (4, c2)):
            dd[1, i, i] = 2.0 * w
        # J = (F_zZ F_rR − F_zR F_rZ) F_θΘ
        for (i, j), value in {(0, 3): F[4], (1, 2): -F[4], (0, 4): F[3], (3, 4): F[0], (1, 4): -F[2],
                              (2, 4): -F[1]}.items():
            dd[2, i, j] = dd[2, j, i] = value
        return d, dd


def _powers(J1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """a = J^(−2/3), a − 1 and s − 1 for s = J^(1/3), from J − 1 to round-off."""
    log = np.log1p(J1)
    return np.exp(-2.0 / 3.0 * log), np.expm1(-2.0 / 3.0 * log), np.expm1(log / 3.0)


@attrs.frozen
class Isochoric:
    """Ψ_iso of the matrix (c) and the fibres (k₁, k₂ at ±β).  Units: c, k₁ in dyn/cm², k₂ dimensionless, β in
    radians; k₁ = 0 is neo-Hookean.

    The fibres' energy φ(Ī₄) = k₁/k₂ (exp(k₂ e²) − 1) with e = Ī₄ − 1 where Ī₄ ≥ 1, 0 elsewhere: C¹ at e = 0, so
    the force is continuous and the tangent jumps by 2k₁ as the fibres start to bear load (at e = 0 exactly, at
    rest, it is the loading one: the fibres' stiffness as the wall is inflated from rest).
    """

    c: float
    k1: float = 0.0
    k2: float = 1.0
    beta: float = 0.0

    def _fibres(self, s: Strain, a: np.ndarray, am1: np.ndarray) -> Energy:
        """The two families' energy φ(Ī₄) = 2 × :func:`~.membrane_laws.hgo_fibre` at e = Ī₄ − 1 = a(I₄ − 1) + (a − 1),
        with φ' and φ'' in Ī₄ (both families stretch alike)."""
        one = hgo_fibre(a * s.I4m1 + am1, self.k1, self.k2)
        return Energy(2.0 * one.value, 2.0 * one.first, 2.0 * one.second)

    def energy(self, s: Strain) -> np.ndarray:
        """Ψ_iso: the matrix c/2 (a I₁ − 3) = c/2 a (Q + (s − 1)²(2s + 1)), s = J^(1/3), and the fibres.

        >>> f"{float(Isochoric(2.0).energy(Strain.of(np.array([1e-9, 0.0, 0.0, 0.0, 0.0]), 0.0))):.9e}"  # (2c/3) ε²
        '1.333333332e-18'
        """
        a, am1, sm1 = _powers(s.J1)
        psi = 0.5 * self.c * a * (s.Q + sm1**2 * (3.0 + 2.0 * sm1))
        if self.k1:
            psi = psi + self._fibres(s, a, am1).value
        return psi

    def stress(self, s: Strain) -> np.ndarray:
        """P = ∂Ψ_iso/∂F (5, ...): the matrix c a (F − (I₁/3) F⁻ᵀ) = c a (H + F⁻ᵀHᵀ − (I₁ − 3)/3 F⁻ᵀ), the fibres
        φ' ∂Ī₄/∂F.

        >>> P = Isochoric(2.0).stress(Strain.of(np.array([1e-9, 0.0, 0.0, 0.0, 0.0]), 0.0))
        >>> [f"{p:.8e}" for p in P]  # 2μ ε_dev: (4/3, 0, 0, −2/3, −2/3) μ ε, and terms of ε²
        ['2.66666666e-09', '0.00000000e+00', '0.00000000e+00', '-1.33333333e-09', '-1.33333333e-09']
        """
        a, am1, _ = _powers(s.J1)
        inv_T = s.cofactor / s.J  # F⁻ᵀ
        Ht = transpose(s.H)
        FinvT_Ht = np.stack([inv_T[0] * Ht[0] + inv_T[1] * Ht[2], inv_T[0] * Ht[1] + inv_T[1] * Ht[3],
                             inv_T[2] * Ht[0] + inv_T[3] * Ht[2], inv_T[2] * Ht[1] + inv_T[3] * Ht[3],
                             inv_T[4] * Ht[4]])
        P = self.c * a * (s.H + FinvT_Ht - s.I1m3 / 3.0 * inv_T)
        if self.k1:
            d1 = self._fibres(s, a, am1).first
            dI4 = 2.0 * np.stack([np.sin(self.beta) ** 2 * s.F[0], 0.0 * s.F[1], np.sin(self.beta) ** 2 * s.F[2],
                                  0.0 * s.F[3], np.cos(self.beta) ** 2 * s.F[4]])
            P = P + d1 * a * (dI4 - 2.0 / 3.0 * s.I4 * inv_T)
        return P

    def derivatives(self, s: Strain) -> tuple[np.ndarray, np.ndarray]:
        """ψ_k (3, ...) and ψ_kl (3, 3, ...): the gradient and Hessian of Ψ_iso in x = (I₁, I₄, J), with
        a = J^(−2/3) the factor of the isochoric invariants Ī = a I."""
        J, I1, I4 = s.J, s.I1, s.I4
        a, am1, _ = _powers(s.J1)
        a1 = -2.0 / 3.0 * a / J  # da/dJ
        a2 = 10.0 / 9.0 * a / J**2  # d²a/dJ²
        c = self.c
        g = np.stack([0.5 * c * a, np.zeros_like(a), 0.5 * c * I1 * a1])
        h = np.zeros((3, 3) + np.shape(a))
        h[0, 2] = h[2, 0] = 0.5 * c * a1
        h[2, 2] = 0.5 * c * I1 * a2
        if self.k1:
            fibres = self._fibres(s, a, am1)
            d1, d2 = fibres.first, fibres.second
            g[1] += d1 * a
            g[2] += d1 * a1 * I4
            h[1, 1] += d2 * a**2
            h[1, 2] += d2 * a * a1 * I4 + d1 * a1
            h[2, 1] = h[1, 2]
            h[2, 2] += d2 * (a1 * I4) ** 2 + d1 * a2 * I4
        return g, h

    def tangent(self, s: Strain) -> np.ndarray:
        """A = ∂²Ψ_iso/∂F² (5, 5, ...).

        At rest the neo-Hookean matrix is linear elasticity with μ = c and a bulk modulus 0 (the volumetric
        part is U's):

        >>> A = Isochoric(2.0).tangent(Strain.of(np.zeros(5), 0.0))
        >>> round(float(A[0, 0]), 12), round(float(A[0, 3]), 12)  # λ + 2μ, λ with λ = −2μ/3
        (2.666666666667, -1.333333333333)
        """
        g, h = self.derivatives(s)
        d, dd = s.derivatives(self.beta)
        return np.einsum("kl...,ki...,lj...->ij...", h, d, d) + np.einsum("k...,kij...->ij...", g, dd)


@attrs.frozen
class Volumetric:
    """U(J) = κ/2 (J − 1)² (κ in dyn/cm²): convex, U(1) = U'(1) = 0, U'' = κ; taken at J − 1."""

    bulk: float

    def derivatives(self, J1: np.ndarray):
        """U, U', U'' at J = 1 + ``J1``.

        >>> [float(x) for x in Volumetric(4.0).derivatives(np.array(0.5))]
        [0.5, 2.0, 4.0]
        """
        return 0.5 * self.bulk * J1**2, self.bulk * J1, np.full_like(J1, self.bulk, dtype=float)


__all__ = ["Isochoric", "Strain", "Volumetric", "transpose"]
