"""``multilayer compare``: variants of one scene, run side by side and measured alike.

Variants come from :mod:`multilayer.variants`, measurements from
:mod:`multilayer.measure`, plots and tables from :mod:`multilayer.report`.
Every variant runs into ``OUT/<label>/``, an ordinary results folder (see
:mod:`multilayer.run`), and the comparison is then made from those folders
alone — ``summary.json``, ``series.csv`` and the wall snapshots — so every
number of ``report.md`` / ``report.json`` can be recomputed from the runs'
own files.  See ``docs/compare.md``.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from multilayer.cli import FAILED, INVALID, OK
from multilayer.measure import RunData, compare_runs, lumen_eta, read_run, without_nan
from multilayer.problems import CaseError
from multilayer.registry import Registry
from multilayer.variants import Variant, invalid_message, load_variants, make_variants, run_variant


def run_variants(loaded: Sequence[tuple[Variant, Any]], out: Path, registry: Registry,
                 log: Callable[[str], None] = print) -> list[RunData]:
    """Run every variant into ``out/<label>/`` and read the folders back.

    A run that raises (a bug, not a failed run) is logged with its traceback
    and kept as a failed variant.
    """
    runs = []
    for i, (variant, case) in enumerate(loaded, start=1):
        folder = out / variant.label
        status, reason = run_variant(case, folder, registry)
        run = read_run(variant.label, folder, status, reason)
        log(f"[{i}/{len(loaded)}] {variant.label}: {status}" + (f" ({reason})" if reason else ""))
        runs.append(run)
    return runs


def write_report(out: Path, variants: Sequence[Variant], runs: Sequence[RunData], registry: Registry,
                 vary: str | None = None) -> dict[str, Any]:
    """``report.json``, ``report.md``, ``probes.png`` and ``eta_spacetime.png`` in ``out``."""
    from multilayer import report

    columns = compare_runs(runs, registry)
    for column, variant in zip(columns, variants):
        column["case_file"] = str(variant.case_file)
        column["overrides"] = list(variant.overrides)
    first = runs[0].case
    data = {
        "title": first.get("title", ""),
        "vary": vary,
        "reference": runs[0].label,
        "variants": columns,
    }
    (out / "report.json").write_text(json.dumps(without_nan(data), indent=2, allow_nan=False) + "\n")
    report.plot_probes(runs, out / "probes.png")
    radius = (first.get("geometry") or {}).get("radius")
    fields = {run.label: lumen_eta(run.folder, radius) for run in runs} if radius else {}
    report.plot_spacetime(fields, out / "eta_spacetime.png")
    (out / "report.md").write_text(report.markdown(data))
    return data


def main(case_files: Sequence[Path], out: Path, vary: str | None, overrides: Sequence[str],
         registry: Registry) -> int:
    """``multilayer compare``: 0 all ran, 1 a variant failed, 2 a variant (or --vary) is invalid."""
    try:
        variants = make_variants(case_files, vary, overrides)
    except CaseError as exc:
        print("compare: invalid command line", file=sys.stderr)
        print(str(exc), file=sys.stderr)
        return INVALID
    loaded, invalid = load_variants(variants, registry)
    if invalid:
        print(invalid_message("compare", variants, invalid), file=sys.stderr)
        return INVALID
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    variants = [v for v, _ in loaded]  # with the snapshot cadence they ran with
    runs = run_variants(loaded, out, registry)
    data = write_report(out, variants, runs, registry, vary)
    failed = [c["label"] for c in data["variants"] if c["status"] != "ok"]
    print(f"report: {out / 'report.md'}")
    if failed:
        print(f"compare: {len(failed)} variant(s) failed: {', '.join(failed)}", file=sys.stderr)
        return FAILED
    return OK
