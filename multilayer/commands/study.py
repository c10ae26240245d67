"""``multilayer study``: speed against error of couplers × Δt (× mesh), against a reference.

The grid is :mod:`multilayer.campaign.planning`'s, the measurements
:mod:`multilayer.campaign.study`'s, the report
:mod:`multilayer.campaign.study_report`'s; see ``docs/study.md``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import attrs

from multilayer.campaign import study_report
from multilayer.campaign.executor import ExecutorError
from multilayer.campaign.planning import (
    REFERENCE,
    grid_options,
    invalid_runs,
    plan,
    run_planned,
)
from multilayer.campaign.study import study_data, unknown_probes
from multilayer.campaign.variants import Variant, invalid_message
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
from multilayer.plugin.problems import CaseError
from multilayer.plugin.registry import Registry
from multilayer.results.campaign import open_campaign
from multilayer.results.files import ResultsError


@attrs.frozen
class StudyOptions:
    """``multilayer study``."""

    case: Path
    out: Path
    couplers: str | None  #: ``--couplers`` as given; None: the case's own
    varies: tuple[str, ...]  #: every ``--vary KEY=A,B,...``
    reference: Path | None  #: ``--reference``
    reference_sets: tuple[str, ...]  #: ``--reference-set``: overrides of the reference alone
    probes: tuple[str, ...] | None  #: ``--probes``; None: every η probe
    reuse: bool
    overrides: tuple[str, ...]
    jobs: int
    scheduler: str | None
    plugins: tuple[str, ...]  #: ``--plugin`` modules, loaded again by every worker
    registry: Registry
    command_line: str  #: written at the top of ``study.md``
    force: bool = False  #: write into a folder refused by default (see results.campaign)

    @classmethod
    def from_args(cls, args: argparse.Namespace, registry: Registry, command_line: str) -> StudyOptions:
        return cls(args.case, args.out, args.couplers, tuple(args.varies), args.reference,
                   tuple(args.reference_sets), tuple(args.probes.split(",")) if args.probes else None, args.reuse,
                   tuple(args.overrides), args.jobs, args.scheduler, tuple(args.plugins), registry, command_line, force=args.force)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("study", help="speed against error: couplers x time steps (x meshes) against a reference")
    case_options(p)
    plugin_options(p)
    p.add_argument("--out", type=Path, required=True, help="study folder; each run goes into OUT/<coupler>/<key=value>/")
    p.add_argument("--couplers", metavar="A,B,...",
                   help="coupler names or inline tables replacing [coupler] (default: the case's own)")
    p.add_argument("--vary", dest="varies", action="append", default=[], metavar="KEY=A,B[,C...]",
                   help="values of a key, e.g. time.dt=1e-4,5e-5 (repeatable: the grid is their product)")
    p.add_argument("--reference", type=Path, metavar="CASE",
                   help="run this case file as the reference (default: the finest run of the highest-order coupler)")
    p.add_argument("--reference-set", dest="reference_sets", action="append", default=[], metavar="KEY=VALUE",
                   help="override a value of the reference only (after --set); without --reference the "
                        "reference is CASE with these overrides, e.g. time.dt=1.5625e-6")
    p.add_argument("--probes", metavar="NAME,...",
                   help="the η probes the errors are measured at (default: every η probe)")
    p.add_argument("--reuse", action="store_true",
                   help="keep the runs already in OUT that ended ok with the same case; run only the others")
    executor_options(p)
    force_option(p)
    p.set_defaults(handler=study, options=StudyOptions.from_args)


def study(options: StudyOptions) -> int:
    """``multilayer study``: 0 every run ok, 1 a run failed (the report is written), 2 invalid input (130, 143
    stopped by SIGINT, SIGTERM: :mod:`multilayer.campaign.executor` stops the runs).

    With ``--reference-set`` and no ``--reference``, the reference is the
    case file with those overrides; ``--reuse`` keeps finished runs of the
    same case.
    """
    o = options
    reference = o.case if o.reference is None and o.reference_sets else o.reference
    try:
        choices, axes, problems = grid_options(o.case, o.out, o.couplers, o.varies, o.jobs, o.overrides, o.registry)
    except CaseError as exc:
        return invalid(f"{o.case}: invalid case", exc.problems)
    if problems:
        return invalid("study: invalid command line", problems)
    planned = plan(o.case, choices, axes, o.overrides)
    variants = [p.variant for p in planned]
    if reference is not None:
        variants.append(Variant(REFERENCE, Path(reference), (*o.overrides, *o.reference_sets)))
    wrong = invalid_runs(variants, o.registry)
    if wrong:
        print(invalid_message("study", variants, wrong, "runs"), file=sys.stderr)
        return INVALID
    try:
        open_campaign(o.out, ("study.json", "study.md", "pareto.png", "orders.png", "tolerance.png"), o.force,
                      runs=[p.folder for p in planned] + ([REFERENCE] if reference is not None else []))
    except ResultsError as exc:
        print(f"study: {exc}", file=sys.stderr)
        return INVALID
    folders = {p.label: o.out / p.folder for p in planned} | ({REFERENCE: o.out / REFERENCE} if reference else {})
    # the reference first: with --jobs 1 it is ready before its first comparison, with more it starts first
    order = variants[-1:] + variants[:-1] if reference is not None else variants
    try:
        runs = run_planned(order, folders, o.jobs, o.registry, o.plugins, o.scheduler, o.reuse)
    except ExecutorError as exc:
        print(f"study: {exc}", file=sys.stderr)
        return INVALID
    runs = {label: runs[label] for label in folders}
    if o.probes is not None:
        unknown = unknown_probes(o.probes, runs)
        if unknown:
            print(str(CaseError(unknown)), file=sys.stderr)
            return INVALID
    data = study_data(planned, runs, choices, axes, o.probes, command=o.command_line, case_file=o.case,
                      overrides=o.overrides)
    study_report.write(o.out, data)
    failed = [label for label, run in runs.items() if run.summary.get("status") != "ok"]
    print(f"report: {o.out / 'study.md'}")
    if failed:
        print(f"study: {len(failed)} run(s) failed: {', '.join(failed)}", file=sys.stderr)
        return FAILED
    return OK
