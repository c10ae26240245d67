"""The long-wave speed of a pressure pulse, in a tube and in the planar channel (docs/fluid.md, docs/figures).

A thin Koiter shell (the wall of cases/pulse-koiter.toml) on a long vessel,
L = 30 cm, R = 0.5 cm, a slow small inlet pulse (t_max = 40 ms, 100 dyn/cm²:
its main wavelength ≈ 25 R, its displacement ≈ 1e-4 R), monolithic
Crank–Nicolson.  The pulse's arrival at z = 4 … 16 cm (the time η first
reaches half its peak) against z gives the measured speed; the outlet's
reflection comes back long after.  Beside it the long-wave speeds

    tube:    c² = R·C0/(2ρ_f)   (Moens–Korteweg: C0 = Eh/(R²(1−σ²)) gives Eh/(2ρ_f R(1−σ²)))
    planar:  c² = R·C0/ρ_f

and the same with the two corrections of linear theory at the pulse's
frequency ω = 2π/t_max (theory §11, "The long-wave speed"):

    viscosity (Womersley):  c_v = c / Re(1/√(1 − F)),  F = 2J1(iκR)/(iκR J0(iκR)) (tube),
                            tanh(κR)/(κR) (planar), κ = √(iωρ_f/μ);
    inertia (the fluid's radial inertia and the wall's, inviscid dispersion):
                            c_d² = S(k)/(k²[ρ_f G(kR) + ρ₁h]),  S = C0 + C1k² + C2k⁴,
                            G = I0(kR)/(k I1(kR)) (tube), coth(kR)/k (planar),
    solved for k with ω = c_d k; the corrected speed is c·(c_v/c)·(c_d/c).

Prints one JSON line per geometry and writes docs/figures/moens-korteweg.png
(η at the probes against t, both geometries).

    python scripts/moens_korteweg.py [OUT_DIR]
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from scipy.optimize import brentq
from scipy.special import iv, jv

import multilayer as ml
from multilayer_plugins.thin_shell import koiter_coefficients

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "cases" / "pulse-koiter.toml"
LENGTH, DURATION, AMPLITUDE = 30.0, 0.04, 100.0
PROBES = (4.0, 7.0, 10.0, 13.0, 16.0)
OVERRIDES = {
    "geometry.length": LENGTH, "mesh.nz": 120, "mesh.nr": 4, "time.end": 0.1, "time.dt": 2.5e-4,
    "coupler": {"model": "monolithic", "scheme": "crank-nicolson"},
    "loads.inlet": {"model": "cosine-pulse", "amplitude": AMPLITUDE, "duration": DURATION},
    "output.probes": [{"name": f"eta_z{z:g}", "quantity": "eta", "z": z} for z in PROBES],
}


def half_peak_time(t: np.ndarray, eta: np.ndarray) -> float:
    """First time |η| reaches half its peak, linear between steps."""
    a = np.abs(eta)
    half = 0.5 * a.max()
    i = int(np.argmax(a >= half))
    return float(t[i - 1] + (half - a[i - 1]) / (a[i] - a[i - 1]) * (t[i] - t[i - 1]))


def long_wave(tube: bool, R: float, rho: float, mu: float, wall: dict) -> dict[str, float]:
    """The long-wave speed and its two corrections at ω = 2π/t_max (module docstring)."""
    C0, C1, C2 = koiter_coefficients(wall["thickness"], wall["young"], wall["poisson"], R)
    mass = wall["density"] * wall["thickness"]
    c = math.sqrt(R * C0 / ((2.0 if tube else 1.0) * rho))
    omega = 2 * math.pi / DURATION
    x = np.sqrt(1j * omega * rho / mu) * R
    F = 2 * jv(1, 1j * x) / (1j * x * jv(0, 1j * x)) if tube else np.tanh(x) / x
    viscous = c / float(np.real(1 / np.sqrt(1 - F)))

    def G(k):
        return iv(0, k * R) / (k * iv(1, k * R)) if tube else 1 / (k * math.tanh(k * R))

    def speed(k):
        return math.sqrt((C0 + C1 * k**2 + C2 * k**4) / (k**2 * (rho * G(k) + mass)))

    k = brentq(lambda k: speed(k) * k - omega, 1e-6, 1e3)
    inertia = speed(k)
    return {"long_wave": c, "viscous_factor": viscous / c, "inertia_factor": inertia / c,
            "corrected": c * (viscous / c) * (inertia / c), "womersley_number": float(abs(x)), "kR": k * R}


def measure(kind: str) -> tuple[dict, ml.Results]:
    case = ml.load_case(CASE, {**OVERRIDES, "geometry.model": kind})
    res = ml.run(case)
    assert res.ok, res.reason
    arrivals = np.array([half_peak_time(res.t, res.probes[f"eta_z{z:g}"]) for z in PROBES])
    measured = float(np.polyfit(arrivals, np.array(PROBES), 1)[0])
    fluid = case.resolved["fluid"]
    theory = long_wave(kind == "axisymmetric", case.geometry.radius, fluid["density"], fluid["viscosity"],
                       case.resolved["layers"][0])
    row = {"geometry": kind, "measured": measured, **theory,
           "off_long_wave": measured / theory["long_wave"] - 1, "off_corrected": measured / theory["corrected"] - 1,
           "ledger": res.summary["energy"]["max_relative_residual"]}
    return row, res


def main(out: Path) -> None:
    fig = Figure(figsize=(11, 4.2), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 2, sharey=True)
    for ax, kind in zip(axes, ("axisymmetric", "planar")):
        row, res = measure(kind)
        print(json.dumps(row))
        for z in PROBES:
            ax.plot(1e3 * res.t, 1e4 * res.probes[f"eta_z{z:g}"], label=f"z = {z:g} cm")
        ax.set_title(f"{'tube' if kind == 'axisymmetric' else 'planar channel'}: measured {row['measured']:.1f} cm/s, "
                     f"long-wave {row['long_wave']:.1f}, corrected {row['corrected']:.1f}", fontsize=9)
        ax.set_xlabel("t (ms)")
    axes[0].set_ylabel("η (µm)")
    axes[0].legend(fontsize=8)
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / "moens-korteweg.png", dpi=110)


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "docs" / "figures")
