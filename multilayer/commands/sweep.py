"""``multilayer sweep``: a grid over any case keys (``[sweep]`` table and ``--vary``), each run in ``OUT/runs/<digest>/``.

Planning, running and collecting are :mod:`multilayer.campaign.sweep`'s and
:mod:`multilayer.campaign.executor`'s; see ``docs/sweeps.md``.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import attrs

from multilayer.campaign.executor import ExecutorError, Job, execute, how, print_err
from multilayer.campaign.sweep import (
    collect,
    figure_name,
    key_problems,
    pending,
    plan,
    read_sweep_table,
    sweep_axes,
    write_plan,
    write_report,
)
from multilayer.commands.common import (
    FAILED,
    INVALID,
    OK,
    case_options,
    executor_options,
    force_option,
    invalid,
    plugin_options,
)
from multilayer.plugin.problems import CaseError, Problem
from multilayer.plugin.registry import Registry
from multilayer.results.campaign import open_campaign
from multilayer.results.files import ResultsError


@attrs.frozen
class SweepOptions:
    """``multilayer sweep``."""

    case: Path
    out: Path  #: the sweep folder: ``runs/<digest>/``, ``plan.json``, the report
    varies: tuple[str, ...]  #: every ``--vary KEY=A,B,...``, replacing or adding a key of ``[sweep] grid``
    overrides: tuple[str, ...]
    jobs: int  #: local workers (:func:`default_jobs` when ``--jobs`` is not given)
    scheduler: str | None
    plugins: tuple[str, ...]  #: ``--plugin`` modules, loaded again by every worker
    registry: Registry
    command_line: str  #: written into ``plan.json`` and at the top of ``sweep.md``
    force: bool = False  #: write into a folder refused by default (see results.campaign)

    @classmethod
    def from_args(cls, args: argparse.Namespace, registry: Registry, command_line: str) -> SweepOptions:
        return cls(args.case, args.out, tuple(args.varies), tuple(args.overrides),
                   default_jobs() if args.jobs is None else args.jobs, args.scheduler, tuple(args.plugins), registry,
                   command_line, force=args.force)


def default_jobs() -> int:
    """Local workers without ``--jobs``: one per core."""
    return os.cpu_count() or 1


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("sweep", help="run a grid over any case keys ([sweep] table and --vary) on Dask, "
                                            "each run in OUT/runs/<digest>/")
    case_options(p)
    plugin_options(p)
    p.add_argument("--out", type=Path, required=True,
                   help="sweep folder: runs/<digest>/, plan.json, sweep.csv, sweep.md, sweep_<key>.png")
    p.add_argument("--vary", dest="varies", action="append", default=[], metavar="KEY=A,B[,C...]",
                   help="values of a key, read like --set values (repeatable; replaces the key in [sweep] grid)")
    executor_options(p, jobs=None, jobs_help="local Dask workers (default: one per core); 1 runs here, "
                                             "one run after the other")
    force_option(p)
    p.set_defaults(handler=sweep, options=SweepOptions.from_args)


def sweep(options: SweepOptions) -> int:
    """``multilayer sweep``: 0 every run ok, 1 a run failed (the report is written), 2 invalid input (130, 143
    stopped by SIGINT, SIGTERM: :mod:`multilayer.campaign.executor` stops the runs; the same command runs the rest)."""
    o = options
    problems = []
    if o.jobs < 1:
        problems.append(Problem("--jobs", o.jobs, "expected an integer >= 1 (local workers)"))
    if o.out.exists() and not o.out.is_dir():
        problems.append(Problem("--out", str(o.out), "a file, not a folder"))
    if problems:
        return invalid("sweep: invalid command line", problems)
    try:
        axes = sweep_axes(read_sweep_table(o.case), o.varies)
    except CaseError as exc:
        return invalid(f"{o.case}: invalid sweep", exc.problems)
    problems = key_problems(o.case, axes, o.overrides, o.registry)
    if problems:
        return invalid(f"{o.case}: invalid sweep (each swept key applied alone to the case)", problems)
    runs, wrong = plan(o.case, axes, o.overrides, o.registry)
    if wrong:
        lines = [f"{label}: {p}" for label, found in wrong.items() for p in found]
        print(f"sweep: {len(wrong)} of {len(wrong) + len(runs)} runs invalid", *lines, sep="\n", file=sys.stderr)
        return INVALID
    keys = list(dict.fromkeys(k for r in runs for k, _ in r.values))
    try:
        open_campaign(o.out, ("plan.json", "sweep.csv", "sweep.md", *(figure_name(k) for k in keys)), o.force,
                      runs=[r.folder for r in runs])
    except ResultsError as exc:
        print(f"sweep: {exc}", file=sys.stderr)
        return INVALID
    write_plan(runs, keys, o.out, o.case, o.overrides, o.command_line)
    todo = pending(runs, o.out)
    where = (f"the Dask scheduler {o.scheduler}" if o.scheduler else
             {"serial": "this process", "dask": f"a local Dask cluster of {min(o.jobs, len(todo))} worker(s)",
              "processes": f"{min(o.jobs, len(todo))} local processes (Dask is not installed)"}[how(o.jobs)])
    print_err(f"sweep: {len(runs)} runs, {len(runs) - len(todo)} already done"
              + (f", {len(todo)} to run on {where}" if todo else ", nothing to run"))
    jobs = [Job(r.label, Path(o.case), r.overrides, o.out / r.folder) for r in todo]
    try:
        execute(jobs, o.jobs, o.registry, o.plugins, log=print_err, scheduler=o.scheduler)
    except ExecutorError as exc:
        print(f"sweep: {exc}", file=sys.stderr)
        return INVALID
    rows = collect(runs, o.out, o.registry)
    write_report(o.out, rows, keys, o.command_line)
    failed = [r for r in rows if r["status"] != "ok"]
    print(f"report: {o.out / 'sweep.md'}")
    if failed:
        print(f"sweep: {len(failed)} run(s) not ok: " + "; ".join(f"{r['digest']} ({r['status']})" for r in failed),
              file=sys.stderr)
        return FAILED
    return OK
