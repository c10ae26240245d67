"""The figures and numbers of docs/boundary-conditions.md: absorption at a matched resistance, an RCR periodic state.

    python scripts/boundary_figures.py [OUT]      # runs into OUT (default results/boundary), figures into docs/figures

1. Absorption: cases/pulse-resistance.toml (outlet R = ρ_f c/R), the same
   scene with p_out = 0, and a reference channel twice as long (its outlet's
   reflection cannot reach z = 3 cm before the end): the wave the outlet
   reflects, seen at a probe, is the run minus the reference.
2. Periodic state: cases/physiological-rcr.toml, pressure and flow at both
   ends, and the cycle-to-cycle change of the outlet pressure.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from multilayer.case.casefile import load_case
from multilayer.results.reading import read_run
from multilayer.runner.loop import run_case

ROOT = Path(__file__).parents[1]
FIGURES = ROOT / "docs" / "figures"
PROBES = ("p_z1", "p_z3")


def run(case: str, out: Path, *sets: str):
    result = run_case(load_case(ROOT / "cases" / f"{case}.toml", sets), out)
    if result.status != "ok":
        raise SystemExit(f"{case}: {result.reason}")
    return read_run(out.name, out).series


def reflection(s, ref, probe: str) -> float:
    return float(np.max(np.abs(s[probe] - ref[probe])))


def absorption(out: Path) -> dict:
    matched = run("pulse-resistance", out / "matched")
    free = run("pulse-resistance", out / "free", "loads.outlet=0.0")
    long = run("pulse-resistance", out / "long", "geometry.length=12.0", "mesh.nz=120")
    ratios = {p: reflection(matched, long, p) / reflection(free, long, p) for p in PROBES}
    fig = Figure(figsize=(9, 4.5))
    FigureCanvasAgg(fig)
    ax = fig.subplots(1, 2, sharey=True)
    for a, probe, z in zip(ax, PROBES, (1, 3)):
        for s, label, style in ((free, "p_out = 0", "C3-"), (matched, "resistance R = ρc/R", "C0-"),
                                (long, "reference (channel 2L)", "k--")):
            a.plot(1e3 * s["t"], s[probe], style, lw=1.2, label=label)
        a.set_title(f"p at z = {z} cm: the reflected wave is {ratios[probe]:.1%} of p_out = 0's")
        a.set_xlabel("t (ms)")
        a.title.set_fontsize(9)
    ax[0].set_ylabel("p (dyn/cm²)")
    ax[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(FIGURES / "absorption.png", dpi=110)
    return {"reflected_vs_p_out_0": ratios}


def periodic(out: Path) -> dict:
    s = run("physiological-rcr", out / "rcr")
    t, n = s["t"], int(round(0.8 / (s["t"][1] - s["t"][0])))
    p_out = s["end.outlet.p"]
    cycles = len(t) // n
    change = [float(np.max(np.abs(p_out[k * n:(k + 1) * n] - p_out[(k - 1) * n:k * n])) / np.max(np.abs(p_out[k * n:(k + 1) * n])))
              for k in range(1, cycles)]
    fig = Figure(figsize=(9, 6))
    FigureCanvasAgg(fig)
    ax = fig.subplots(2, 1, sharex=True)
    ax[0].plot(t, s["end.inlet.p"], label="inlet p")
    ax[0].plot(t, p_out, label="outlet p")
    ax[0].plot(t, s["end.outlet.P_c"], "--", label="capacitor P_c")
    ax[0].set_ylabel("p (dyn/cm²)")
    ax[0].legend(fontsize=8)
    ax[1].plot(t, -s["end.inlet.Q"], label="inflow Q_in")
    ax[1].plot(t, s["end.outlet.Q"], label="outflow Q_out")
    ax[1].set_ylabel("Q (cm²/s per unit depth)")
    ax[1].set_xlabel("t (s)")
    ax[1].legend(fontsize=8)
    ax[0].set_title("RCR outlet: cycle-to-cycle change of the outlet pressure " + ", ".join(f"{c:.2%}" for c in change))
    ax[0].title.set_fontsize(9)
    fig.tight_layout()
    fig.savefig(FIGURES / "rcr-periodic.png", dpi=110)
    m = slice((cycles - 1) * n, cycles * n)
    return {"cycle_to_cycle_change": change, "last_cycle": {
        "inflow_mean": float(-s["end.inlet.Q"][m].mean()), "outflow_mean": float(s["end.outlet.Q"][m].mean()),
        "outlet_p_min": float(p_out[m].min()), "outlet_p_max": float(p_out[m].max()),
        "max_relative_residual": float(np.max(s["energy.relative_residual"]))}}


def main(argv: list[str]) -> None:
    out = Path(argv[0]) if argv else ROOT / "results" / "boundary"
    FIGURES.mkdir(parents=True, exist_ok=True)
    print(json.dumps({"absorption": absorption(out), "periodic": periodic(out)}, indent=2))


if __name__ == "__main__":
    main(sys.argv[1:])
