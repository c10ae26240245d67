"""The peaks of some runs' probes against a reference run's, one Markdown row per run.

    python scripts/peak_table.py --reference REF_DIR --probes eta_z1,eta_z2,eta_z3,eta_z4 \
        'LABEL=RUN_DIR' ['LABEL=RUN_DIR' ...]

The reference's row gives its peaks (max over time of each probe, µm for an ``eta`` probe); every other row the
relative difference of its peaks from those, its Δt, the energy ledger's largest relative residual and its wall
time, from each folder's ``series.csv`` and ``summary.json``.  docs/verification.md has this table of the
quick start, made by scripts/verification_report.py.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from multilayer.campaign.run_tables import peak_changes, peaks, signed_percent
from multilayer.results.reading import read_run


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", help="LABEL=RUN_DIR")
    ap.add_argument("--reference", type=Path, required=True)
    ap.add_argument("--probes", required=True)
    args = ap.parse_args(argv)
    probes = args.probes.split(",")
    ref = read_run(args.reference.name, args.reference)
    ref_peaks = peaks(ref, probes)

    def row(label: str, run, cells: list[str]) -> str:
        s = run.summary
        return (f"| {label} | {s['dt']:g} | " + " | ".join(cells)
                + f" | {s['energy']['max_relative_residual']:.1e} | {s['wall_time_s']:.3g} |")

    print("| run | Δt (s) | " + " | ".join(probes) + " | ledger | wall time (s) |")
    print("|---" * (len(probes) + 4) + "|")
    print(row("reference", ref, [f"{1e4 * p:.2f} µm" if name.startswith("eta") else f"{p:.6g}"
                                 for name, p in zip(probes, ref_peaks)]))
    for item in args.runs:
        label, _, folder = item.rpartition("=")
        run = read_run(Path(folder).name, Path(folder))
        print(row(label, run, [signed_percent(c) for c in peak_changes(run, ref, probes)]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
