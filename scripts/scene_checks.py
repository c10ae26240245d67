"""What a hemodynamics scene's runs show, as Markdown tables: ledgers, pressures in mmHg, the periodic state, the
centreline velocity against the section's mean, and its change between successive runs (a mesh refinement).

    python scripts/scene_checks.py RUN_DIR [RUN_DIR ...] --radius 0.3 \
        [--centreline u_axis_z3:q_mid:eta_z3,u_axis_z55:q_out:eta_z55] [--pressure p_out] [--period 1.0]

Each RUN_DIR is a results folder (``multilayer run --out``).  Per run: status, steps, the energy ledger's largest
relative residual, the volume's relative drift (summary.json), the range of ``--pressure`` over the last period
and its largest change from the period before (relative to its peak), and for each ``probe:section:eta``
triple the range of the centreline probe over the section's mean velocity Q/(π(R + η)²) (the section as the
wall has moved it) at the rows where that mean exceeds 5 cm/s.  With several runs, the largest change of each centreline probe between successive runs (interpolated
onto the first run's times that every run reached): the mesh-refinement table of docs/accuracy.md, "The carotid-like artery".
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from multilayer.plugin.units import MMHG
from multilayer.results.reading import read_run

FLOWING = 5.0  # cm/s: the mean velocity above which the centreline ratio is read


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", type=Path, nargs="+")
    ap.add_argument("--radius", type=float, required=True, help="the lumen's radius at rest (cm)")
    ap.add_argument("--centreline", default="u_axis_z3:q_mid:eta_z3,u_axis_z55:q_out:eta_z55")
    ap.add_argument("--pressure", default="p_out")
    ap.add_argument("--period", type=float, default=1.0, help="the cycle (s)")
    args = ap.parse_args(argv)
    pairs = [tuple(item.split(":")) for item in args.centreline.split(",")]
    runs = [read_run(folder.name, folder) for folder in args.runs]
    print("| run | status | steps | energy | volume drift | " + f"{args.pressure} last cycle (mmHg) | periodic | "
          + " | ".join(f"{probe} / mean" for probe, _, _ in pairs) + " |")
    print("|---" * (7 + len(pairs)) + "|")
    for folder, run in zip(args.runs, runs):
        s, t, summary = run.series, run.t, run.summary
        p = s[args.pressure] / MMHG
        last = t > t[-1] - args.period
        before = (t > t[-1] - 2 * args.period) & ~last
        periodic = "—"
        if t[-1] >= 2 * args.period - 1e-9 and before.any():
            shifted = np.interp(t[last] - args.period, t[before], p[before])
            periodic = f"{np.max(np.abs(p[last] - shifted)) / np.max(np.abs(p[last])):.2%}"
        ratios = []
        for probe, section, eta in pairs:
            mean = s[section] / (np.pi * (args.radius + s[eta]) ** 2)
            flowing = mean > FLOWING
            r = s[probe][flowing] / mean[flowing]
            ratios.append(f"{r.min():.2f} … {r.max():.2f}")
        print(f"| {folder.name} | {summary['status']} | {summary['steps']} | "
              f"{summary['energy']['max_relative_residual']:.1e} | {summary['volume']['relative_drift']:.2e} | "
              f"{p[last].min():.1f} … {p[last].max():.1f} | {periodic} | " + " | ".join(ratios) + " |")
    if len(runs) > 1:
        print()
        print("| runs | " + " | ".join(f"max change of {probe} (cm/s)" for probe, _, _ in pairs) + " |")
        print("|---" * (1 + len(pairs)) + "|")
        t0 = runs[0].t[runs[0].t <= min(run.t[-1] for run in runs)]  # the times every run reached
        for (fa, a), (fb, b) in zip(zip(args.runs, runs), zip(args.runs[1:], runs[1:])):
            changes = [np.max(np.abs(np.interp(t0, a.t, a.series[probe]) - np.interp(t0, b.t, b.series[probe])))
                       for probe, _, _ in pairs]
            print(f"| {fa.name} → {fb.name} | " + " | ".join(f"{c:.2f}" for c in changes) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
