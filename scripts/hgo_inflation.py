"""The inflation of an incompressible thick-walled tube of hyperelastic layers: inner radius against pressure
(docs/theory-wall.md, "Inflation of a hyperelastic tube").  The reference of ``tests/test_hyperelastic_inflation.py``.

    python scripts/hgo_inflation.py [--stretch 1.0 1.5] [--pressures 0 2 4 ... 20]

prints r_i (mm) against P (kPa) for the two-layer rabbit carotid of Holzapfel, Gasser & Ogden (2000): media
c = 3.0 kPa, k₁ = 2.3632 kPa, k₂ = 0.8393, β = 29°, H = 0.26 mm; adventitia c = 0.3 kPa, k₁ = 0.562 kPa,
k₂ = 0.7112, β = 62°, H = 0.13 mm; R_i = 0.71 mm unloaded, no residual stress, ends at the axial stretch λ_z.

An incompressible tube inflated at a fixed λ_z maps the reference radius R to r with
r² = r_i² + (R² − R_i²)/λ_z (the volume between R_i and R kept); the stretches are λ_θ = r/R, λ_z and
λ_r = 1/(λ_θ λ_z).  The radial equilibrium dσ_rr/dr + (σ_rr − σ_θθ)/r = 0 with σ_rr(r_i) = −P and
σ_rr(r_o) = 0 gives

    P = ∫_{r_i}^{r_o} (σ_θθ − σ_rr) dr/r = ∫_{R_i}^{R_o} (σ_θθ − σ_rr) R/(λ_z r²) dR,

with σ_θθ − σ_rr = λ_θ ∂Ψ/∂λ_θ − λ_r ∂Ψ/∂λ_r of the isochoric energy (the hydrostatic pressure drops out):
c (λ_θ² − λ_r²) for the matrix, 4 k₁ E exp(k₂E²) λ_θ² cos²β for the two fibre families, E = I₄ − 1 > 0,
I₄ = λ_θ² cos²β + λ_z² sin²β.  The integral is taken layer by layer (scipy's adaptive quadrature in R), and
r_i(P) by a root-finder.  For a neo-Hookean tube the integral has a closed form (:func:`neo_hookean_pressure`),
which a test checks the quadrature against.

Units: CGS (cm, dyn/cm²; 1 kPa = 10⁴ dyn/cm²).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

import attrs
import numpy as np
from scipy.integrate import quad
from scipy.optimize import brentq

KPA = 1.0e4  # dyn/cm²


@attrs.frozen
class Layer:
    """A layer of the tube: its unloaded thickness (cm), c and k₁ (dyn/cm²), k₂, β (degrees)."""

    thickness: float
    c: float
    k1: float = 0.0
    k2: float = 1.0
    beta: float = 0.0

    def difference(self, lt: float, lz: float) -> float:
        """σ_θθ − σ_rr (dyn/cm²) at the hoop stretch ``lt`` and the axial stretch ``lz``."""
        lr = 1.0 / (lt * lz)
        out = self.c * (lt**2 - lr**2)
        cos2 = np.cos(np.deg2rad(self.beta)) ** 2
        E = lt**2 * cos2 + lz**2 * (1.0 - cos2) - 1.0
        if self.k1 and E > 0.0:
            out += 4.0 * self.k1 * E * np.exp(self.k2 * E**2) * lt**2 * cos2
        return out


#: the rabbit carotid of Holzapfel, Gasser & Ogden (2000), Table 1 and §4: media, adventitia
CAROTID = (Layer(0.026, 3.0 * KPA, 2.3632 * KPA, 0.8393, 29.0), Layer(0.013, 0.3 * KPA, 0.562 * KPA, 0.7112, 62.0))
#: its unloaded inner radius (cm)
INNER = 0.071


def radius(R: float, r_inner: float, R_inner: float, lz: float) -> float:
    """r(R) of the incompressible tube with deformed inner radius ``r_inner``."""
    return np.sqrt(r_inner**2 + (R**2 - R_inner**2) / lz)


def pressure(r_inner: float, lz: float, layers: Sequence[Layer] = CAROTID, R_inner: float = INNER) -> float:
    """P (dyn/cm²) that holds the tube at the inner radius ``r_inner`` (cm) and the axial stretch ``lz``."""
    total, R0 = 0.0, R_inner
    for layer in layers:
        R1 = R0 + layer.thickness

        def integrand(R, layer=layer):
            r = radius(R, r_inner, R_inner, lz)
            return layer.difference(r / R, lz) * R / (lz * r**2)

        total += quad(integrand, R0, R1, epsabs=1e-9, epsrel=1e-13, limit=200)[0]
        R0 = R1
    return total


def inner_radius(P: float, lz: float, layers: Sequence[Layer] = CAROTID, R_inner: float = INNER) -> float:
    """r_i (cm) at the pressure ``P`` (dyn/cm²) and the axial stretch ``lz``: the root of pressure(r_i) = P."""
    low, high = 0.2 * R_inner / np.sqrt(lz), 5.0 * R_inner
    return brentq(lambda r: pressure(r, lz, layers, R_inner) - P, low, high, xtol=1e-15, rtol=1e-14)


def neo_hookean_pressure(r_inner: float, lz: float, c: float, R_inner: float, R_outer: float) -> float:
    """P of one neo-Hookean layer in closed form: with u = r², A = r_i² − R_i²/λ_z,
    P = c/(2λ_z) [ln((u − A)/u) − A/u] from u_i to u_o."""
    A = r_inner**2 - R_inner**2 / lz
    u_i, u_o = r_inner**2, radius(R_outer, r_inner, R_inner, lz) ** 2

    def F(u):
        return np.log((u - A) / u) - A / u

    return c / (2.0 * lz) * (F(u_o) - F(u_i))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stretch", type=float, nargs="+", default=[1.0, 1.5], help="axial stretches λ_z")
    ap.add_argument("--pressures", type=float, nargs="+", default=list(range(0, 21, 2)), help="P in kPa")
    args = ap.parse_args(argv)
    print("| P (kPa) | " + " | ".join(f"r_i (mm), λ_z = {lz:g}" for lz in args.stretch) + " |")
    print("|---|" + "---|" * len(args.stretch))
    for P in args.pressures:
        row = [f"{10.0 * inner_radius(P * KPA, lz):.6f}" for lz in args.stretch]
        print(f"| {P:g} | " + " | ".join(row) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
