"""Strain energies of arterial tissue and their reduction to an incompressible membrane Ψ(λθ, λz).

The laws, in the invariants of C = FᵀF (I1 = tr C; I4 = a·Ca, the squared
stretch of a fibre of direction a):

* :func:`neo_hookean`: the isotropic matrix, W = c/2 (I1 − 3);
* :func:`hgo_fibre`: one fibre family of Holzapfel, Gasser & Ogden (2000),
  W = k1/(2k2) (exp(k2 (I4 − 1)²) − 1), which bears load only in extension
  (I4 > 1; W = 0 below).

Each returns the energy and its first and second derivatives in its
invariant (:class:`Energy`), at arrays of invariants.

:func:`membrane_energy` reduces them to a thin, incompressible wall
stretched by λθ around and λz along, with no shear (the kinematics of an
axisymmetric wall without torsion): the thickness stretch is 1/(λθλz), so

    I1 = λθ² + λz² + λθ⁻²λz⁻²,     I4 = λθ² cos²β + λz² sin²β

for both families at ±β to the circumferential direction (they stretch
alike), and Ψ(λθ, λz) = W_matrix(I1) + 2 W_fibre(I4), with its gradient and
Hessian in (λθ, λz) by the chain rule (:class:`MembraneEnergy`).  The
membrane is in plane stress: the thickness pressure that incompressibility
adds is eliminated by σ_rr = 0, which the reduced Ψ has built in.

At rest (λθ = λz = 1) the neo-Hookean membrane's hoop stiffness is
Ψ_θθ = 4c, the plane-stress modulus E/(1 − σ²) of E = 3c, σ = ½:

>>> law = MembraneLaw(c=1.0)
>>> e = law.energy(np.array([1.0]), np.array([1.0]))
>>> float(e.value[0]), float(e.d_theta[0]), float(e.d_theta_theta[0]), float(e.d_theta_z[0])
(0.0, 0.0, 4.0, 2.0)
"""

from __future__ import annotations

import math

import attrs
import numpy as np


@attrs.frozen(eq=False)
class Energy:
    """A strain energy W(I) at an array of invariants I, with W'(I) and W''(I)."""

    value: np.ndarray
    first: np.ndarray
    second: np.ndarray


def neo_hookean(I1: np.ndarray, c: float) -> Energy:
    """The neo-Hookean matrix W = c/2 (I1 − 3) (c the shear modulus μ, dyn/cm²).

    >>> e = neo_hookean(np.array([3.0, 4.0]), 2.0)
    >>> e.value.tolist(), e.first.tolist(), e.second.tolist()
    ([0.0, 1.0], [1.0, 1.0], [0.0, 0.0])
    """
    I1 = np.asarray(I1, dtype=float)
    return Energy(0.5 * c * (I1 - 3.0), np.full_like(I1, 0.5 * c), np.zeros_like(I1))


def hgo_fibre(E: np.ndarray, k1: float, k2: float) -> Energy:
    """One HGO fibre family at its strain E = I4 − 1: W = k1/(2k2) (exp(k2 E²) − 1) in extension (E ≥ 0), W = 0 in
    compression (k1 dyn/cm², k2 dimensionless; k2 = 0 is the limit k1 E²/2).  W' and W'' are in I4.

    E is taken as its caller forms it, from strains that vanish at rest, so that E = 0 there exactly (I4 − 1
    formed from I4 would not be).  W is C¹ at E = 0 (W' = k1 E exp(k2E²) → 0) but W'' jumps there from 0 to
    k1: at E = 0 exactly the second derivative is the loading one, k1 (the fibres' stiffness as the wall is
    inflated from rest).

    >>> e = hgo_fibre(np.array([-0.1, 0.0, 0.1]), 2.0, 0.0)
    >>> e.value.round(12).tolist(), e.first.round(12).tolist(), e.second.tolist()
    ([0.0, 0.0, 0.01], [0.0, 0.0, 0.2], [0.0, 2.0, 2.0])
    >>> hgo_fibre(np.array([30.0]), 2.0, 1.0).value.tolist()  # exp(900): beyond float range, no warning
    [inf]
    """
    E = np.asarray(E, dtype=float)
    active = E >= 0.0
    E = np.where(active, E, 0.0)
    x = k2 * E * E
    # beyond exp's range (k₂E² > 709, a trial state far out) W, W' and W'' are inf, without a warning: the solve
    # that tried the state rejects it (multilayer.numerics.newton.at_trial)
    with np.errstate(over="ignore", invalid="ignore"):
        growth = np.exp(x)
        # k1/(2k2) expm1(k2E²) = k1E²/2 · expm1(x)/x, finite as k2 → 0
        ratio = np.where(x > 0.0, np.expm1(x) / np.where(x > 0.0, x, 1.0), 1.0)
        value = 0.5 * k1 * E * E * ratio
        first = k1 * E * growth
        second = np.where(active, k1 * growth * (1.0 + 2.0 * x), 0.0)
    return Energy(value, first, second)


@attrs.frozen(eq=False)
class MembraneEnergy:
    """Ψ(λθ, λz) of a membrane at arrays of stretches, with its gradient and Hessian in (λθ, λz)."""

    value: np.ndarray
    d_theta: np.ndarray
    d_z: np.ndarray
    d_theta_theta: np.ndarray
    d_theta_z: np.ndarray
    d_z_z: np.ndarray


@attrs.frozen
class MembraneLaw:
    """A neo-Hookean matrix (c) with two HGO fibre families at ±``angle`` (degrees) to the circumferential
    direction (k1, k2; k1 = 0: no fibres, the neo-Hookean law), reduced to an incompressible membrane."""

    c: float = attrs.field(converter=float, validator=attrs.validators.gt(0.0))  #: dyn/cm²
    k1: float = attrs.field(default=0.0, converter=float, validator=attrs.validators.ge(0.0))  #: dyn/cm²
    k2: float = attrs.field(default=0.0, converter=float, validator=attrs.validators.ge(0.0))  #: 1
    angle: float = attrs.field(default=0.0, converter=float,
                               validator=[attrs.validators.ge(0.0), attrs.validators.le(90.0)])  #: β (deg)

    def energy(self, stretch_theta: np.ndarray, stretch_z: np.ndarray) -> MembraneEnergy:
        """Ψ = W_matrix(I1) + 2 W_fibre(I4) and its derivatives at the stretches (λθ, λz)."""
        x, y = np.asarray(stretch_theta, dtype=float), np.asarray(stretch_z, dtype=float)
        # I1 = x² + y² + x⁻²y⁻² (the thickness stretch 1/(xy)): gradient and Hessian in (x, y)
        r2 = 1.0 / (x * x * y * y)
        I1 = (x * x + y * y + r2, 2.0 * x - 2.0 * r2 / x, 2.0 * y - 2.0 * r2 / y,
              2.0 + 6.0 * r2 / (x * x), 4.0 * r2 / (x * y), 2.0 + 6.0 * r2 / (y * y))
        parts = [(neo_hookean(I1[0], self.c), I1, 1.0)]
        if self.k1 > 0.0:
            cos2, sin2 = math.cos(math.radians(self.angle)) ** 2, math.sin(math.radians(self.angle)) ** 2
            # I4 − 1 (the first entry) summed from the stretches' own strains, so that it is 0 exactly at rest
            # (cos² + sin² need not round to 1) and the fibres' loading stiffness counts there
            I4 = ((x * x - 1.0) * cos2 + (y * y - 1.0) * sin2, 2.0 * x * cos2, 2.0 * y * sin2,
                  np.full_like(x, 2.0 * cos2), np.zeros_like(x), np.full_like(x, 2.0 * sin2))
            parts.append((hgo_fibre(I4[0], self.k1, self.k2), I4, 2.0))  # two families, stretched alike
        out = [np.zeros_like(x) for _ in range(6)]
        for w, (_, gx, gy, hxx, hxy, hyy), n in parts:
            out[0] += n * w.value
            out[1] += n * w.first * gx
            out[2] += n * w.first * gy
            out[3] += n * (w.second * gx * gx + w.first * hxx)
            out[4] += n * (w.second * gx * gy + w.first * hxy)
            out[5] += n * (w.second * gy * gy + w.first * hyy)
        return MembraneEnergy(*out)


__all__ = ["Energy", "MembraneEnergy", "MembraneLaw", "hgo_fibre", "neo_hookean"]
