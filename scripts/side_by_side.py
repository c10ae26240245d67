"""Runs of one case measured side by side: steps, median wall time, errors against a reference folder.

    python scripts/side_by_side.py CASE --reference DIR --out DIR --probes eta_z1,eta_z2,eta_z3 \
        [--set KEY=VALUE]... --run 'LABEL:KEY=VALUE;KEY=VALUE' ... [--repeat 3]

Every ``--run`` is the case with the ``--set`` overrides, then its own.  The
runs take turns (run 1, run 2, ..., then again), ``--repeat`` times each,
into ``OUT/LABEL/i``, so a shared machine's load falls on all of them alike.
Prints a Markdown table: status, accepted steps, the median wall time, and
the largest over the probes of the relative L∞ error and the peak error
(``multilayer.campaign.accuracy.probe_errors``) against the reference run's
folder (its series interpolated linearly onto each run's times).
docs/accuracy.md, "Adaptive steps", uses it for the cost of a target error.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

from multilayer.campaign.accuracy import probe_errors
from multilayer.case.casefile import load_case
from multilayer.results.reading import read_run
from multilayer.runner.loop import run_case


def errors(folder: Path, reference, probes: list[str]) -> tuple[float, float]:
    """(L∞ error, peak error), each the largest over ``probes``."""
    run = read_run(folder.name, folder)
    found = [probe_errors(run.t, run.series[p], reference.t, reference.series[p]) for p in probes]
    return max(e["relative_linf"] for e in found), max(e["peak_error"] for e in found)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case", type=Path)
    ap.add_argument("--reference", type=Path, required=True, help="the reference run's results folder")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--probes", required=True, help="comma list of η probe names")
    ap.add_argument("--set", dest="sets", action="append", default=[])
    ap.add_argument("--run", dest="runs", action="append", required=True, help="LABEL:KEY=VALUE;KEY=VALUE")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    probes = args.probes.split(",")
    reference = read_run("reference", args.reference)
    runs = [(text.split(":", 1)[0], [s for s in text.split(":", 1)[1].split(";") if s]) for text in args.runs]
    times: dict[str, list[float]] = {label: [] for label, _ in runs}
    last: dict[str, tuple] = {}
    for i in range(args.repeat):
        for label, sets in runs:
            folder = args.out / label / str(i)
            result = run_case(load_case(args.case, [*args.sets, *sets]), folder, force=True)
            summary = read_run(label, folder).summary
            times[label].append(summary["wall_time_s"])
            last[label] = (result.status, summary.get("adaptive", {}).get("accepted", summary["steps"]),
                           summary.get("adaptive", {}).get("rejected", 0), folder)
            print(f"{label} #{i}: {result.status}, {summary['wall_time_s']:.3g} s", file=sys.stderr)
    print("| run | status | steps (rejected) | median wall time (s) | wall times (s) | L∞ error | peak error |")
    print("|---|---|---|---|---|---|---|")
    for label, _ in runs:
        status, steps, rejected, folder = last[label]
        linf, peak = errors(folder, reference, probes) if status == "ok" else (float("nan"), float("nan"))
        print(f"| `{label}` | {status} | {steps} ({rejected}) | {statistics.median(times[label]):.3g} | "
              f"{', '.join(f'{t:.3g}' for t in times[label])} | {100 * linf:.3g} % | {100 * peak:.3g} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
