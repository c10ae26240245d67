"""Runs of one case measured side by side: steps, median wall time, errors against a reference folder.

    python scripts/side_by_side.py CASE --reference DIR --out DIR --probes eta_z1,eta_z2,eta_z3 \
        [--set KEY=VALUE]... --run 'LABEL:KEY=VALUE;KEY=VALUE' ... [--repeat 3] [--after SECONDS] [--measure-only]

Every ``--run`` is the case with the ``--set`` overrides, then its own.  The
runs take turns (run 1, run 2, ..., then again), ``--repeat`` times each,
into ``OUT/LABEL/i``, so a shared machine's load falls on all of them alike.
Prints a Markdown table: status, accepted steps, the steps' range, the median
wall time, and the largest over the probes of the relative L∞ error and the
peak error (``multilayer.campaign.run_tables.errors_against``) against the
reference run's folder (its series interpolated linearly onto each run's
times), over the rows with t ≥ ``--after`` (all by default).  ``--measure-only``
measures the runs an earlier call left in OUT again, running nothing.
scripts/verification_report.py makes the same table for the studies of docs/verification.md.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

from multilayer.campaign.run_tables import dt_cell, errors_against, percent, steps_taken
from multilayer.case.casefile import load_case
from multilayer.results.reading import read_run
from multilayer.runner.loop import run_case


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case", type=Path)
    ap.add_argument("--reference", type=Path, required=True, help="the reference run's results folder")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--probes", required=True, help="comma list of η probe names")
    ap.add_argument("--set", dest="sets", action="append", default=[])
    ap.add_argument("--run", dest="runs", action="append", required=True, help="LABEL:KEY=VALUE;KEY=VALUE")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--after", type=float, default=0.0,
                    help="measure the errors over t ≥ AFTER only (s; a periodic run's last cycle)")
    ap.add_argument("--measure-only", action="store_true",
                    help="run nothing: measure the runs an earlier call left in OUT (other probes, another --after)")
    args = ap.parse_args(argv)
    probes = args.probes.split(",")
    reference = read_run("reference", args.reference)
    runs = [(text.split(":", 1)[0], [s for s in text.split(":", 1)[1].split(";") if s]) for text in args.runs]
    times: dict[str, list[float]] = {label: [] for label, _ in runs}
    last: dict[str, tuple] = {}
    for i in range(args.repeat):
        for label, sets in runs:
            folder = args.out / label / str(i)
            if not args.measure_only:
                run_case(load_case(args.case, [*args.sets, *sets]), folder, force=True)
            summary = read_run(label, folder).summary
            times[label].append(summary["wall_time_s"])
            last[label] = (summary["status"], *steps_taken(summary), folder)
            print(f"{label} #{i}: {summary['status']}, {summary['wall_time_s']:.3g} s", file=sys.stderr)
    print("| run | status | steps (rejected) | Δt (s) | median wall time (s) | wall times (s) | L∞ error | peak error |")
    print("|---|---|---|---|---|---|---|---|")
    for label, _ in runs:
        status, steps, rejected, (small, large), folder = last[label]
        linf, peak = (errors_against(read_run(label, folder), reference, probes, args.after) if status == "ok"
                      else (float("nan"),) * 2)
        print(f"| `{label}` | {status} | {steps} ({rejected}) | {dt_cell(small, large)} | "
              f"{statistics.median(times[label]):.3g} | {', '.join(f'{t:.3g}' for t in times[label])} | "
              f"{percent(linf)} | {percent(peak)} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
