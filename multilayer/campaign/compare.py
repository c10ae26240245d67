"""``multilayer compare``: variants of one scene, run side by side and measured alike.

Variants come from :mod:`multilayer.campaign.variants`, measurements from
:mod:`multilayer.campaign.measures`, plots and tables from :mod:`multilayer.campaign.report`.
Every variant runs into ``OUT/<label>/``, an ordinary results folder (see
:mod:`multilayer.runner.loop`), and the comparison is then made from those folders
alone — ``summary.json``, ``series.csv`` and the wall snapshots — so every
number of ``report.md`` / ``report.json`` can be recomputed from the runs'
own files.  See ``docs/compare.md``; the command line is
:mod:`multilayer.commands.compare`.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from multilayer.campaign import report
from multilayer.campaign.executor import Job, execute
from multilayer.campaign.measures import compare_runs
from multilayer.campaign.variants import Variant
from multilayer.plugin.registry import Registry
from multilayer.results.campaign import claim
from multilayer.results.files import write_atomically
from multilayer.results.reading import RunData, lumen_eta, read_run, without_nan


def run_variants(variants: Sequence[Variant], out: Path, registry: Registry, jobs: int = 1,
                 plugins: Sequence[str] = (), scheduler: str | None = None,
                 log: Callable[[str], None] = print) -> list[RunData]:
    """Run every variant into ``out/<label>/`` with :func:`multilayer.campaign.executor.execute` and read the folders back.

    A run that raises (a bug, not a failed run) is logged with its traceback
    and kept as a failed variant.  ``jobs`` 1 runs them here, one after the
    other; more (or a ``scheduler``) on Dask.
    """
    work = [Job(v.label, v.case_file, v.overrides, out / v.label) for v in variants]
    status = execute(work, jobs, registry, plugins, log=log, scheduler=scheduler)
    return [read_run(v.label, out / v.label, *status[v.label]) for v in variants]


def write_report(out: Path, variants: Sequence[Variant], runs: Sequence[RunData], registry: Registry,
                 vary: str | None = None) -> dict[str, Any]:
    """``report.json``, ``report.md``, ``probes.png`` and ``eta_spacetime.png`` in ``out``."""
    # matplotlib is heavy (results.figures loads it): imported only when the figures are drawn
    from multilayer.results.figures import plot_spacetime

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
    write_atomically(claim(out, "report.json"), json.dumps(without_nan(data), indent=2, allow_nan=False) + "\n")
    report.plot_compared_probes(runs, claim(out, "probes.png"))
    radius = (first.get("geometry") or {}).get("radius")
    fields = {run.label: lumen_eta(run.folder, radius) for run in runs} if radius else {}
    plot_spacetime(fields, claim(out, "eta_spacetime.png"), title=first.get("title") or None)
    write_atomically(claim(out, "report.md"), report.markdown(data))
    return data
