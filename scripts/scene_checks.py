"""What a hemodynamics scene's runs show, as Markdown tables: ledgers, pressures in mmHg, the periodic state, the
centreline velocity against the section's mean, and its change between successive runs (a mesh refinement).

    python scripts/scene_checks.py RUN_DIR [RUN_DIR ...] --radius 0.3 \
        [--centreline u_axis_z3:q_mid:eta_z3,u_axis_z55:q_out:eta_z55] [--pressure p_out] [--period 1.0]

Each RUN_DIR is a results folder (``multilayer run --out``).  Per run: status, steps, the energy ledger's largest
relative residual, the volume's relative drift (summary.json), the range of ``--pressure`` over the last period
and its largest change from the period before (relative to its peak), and for each ``probe:section:eta``
triple the range of the centreline probe over the section's mean velocity Q/(π(R + η)²) (the section as the
wall has moved it) at the rows where that mean exceeds 5 cm/s.  With several runs, the largest change of each centreline probe between successive runs (interpolated
onto the first run's times that every run reached): the tables of docs/verification.md's carotid studies
(scripts/verification_report.py).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from multilayer.campaign.run_tables import (
    centreline_changes,
    markdown,
    scene_cells,
    scene_header,
)
from multilayer.results.reading import read_run


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
    print("\n".join(markdown(["run", *scene_header(pairs, args.pressure)],
                             [[folder.name, *scene_cells(run, args.radius, pairs, args.pressure, args.period)]
                              for folder, run in zip(args.runs, runs)])))
    if len(runs) > 1:
        print()
        t0 = runs[0].t[runs[0].t <= min(run.t[-1] for run in runs)]  # the times every run reached
        probes = [probe for probe, _, _ in pairs]
        print("\n".join(markdown(["runs", *(f"max change of {probe} (cm/s)" for probe in probes)],
                                 [[f"{fa.name} → {fb.name}", *(f"{c:.2f}" for c in centreline_changes(a, b, probes, t0))]
                                  for (fa, a), (fb, b) in zip(zip(args.runs, runs), zip(args.runs[1:], runs[1:]))])))
    return 0


if __name__ == "__main__":
    sys.exit(main())
