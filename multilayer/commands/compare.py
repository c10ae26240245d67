"""``multilayer compare``: run variants of a scene side by side and report the differences.

The variants, their runs and the report are :mod:`multilayer.campaign.variants`
and :mod:`multilayer.campaign.compare`; see ``docs/compare.md``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import attrs

from multilayer.campaign.compare import run_variants, write_report
from multilayer.campaign.executor import ExecutorError
from multilayer.campaign.variants import invalid_message, load_variants, make_variants
from multilayer.commands.common import (
    FAILED,
    INVALID,
    OK,
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
class CompareOptions:
    """``multilayer compare``."""

    cases: tuple[Path, ...]
    out: Path
    vary: str | None
    overrides: tuple[str, ...]
    jobs: int
    scheduler: str | None
    plugins: tuple[str, ...]  #: ``--plugin`` modules, loaded again by every worker
    registry: Registry
    force: bool = False  #: write into a folder refused by default (see results.campaign)

    @classmethod
    def from_args(cls, args: argparse.Namespace, registry: Registry, command_line: str) -> CompareOptions:
        return cls(tuple(args.cases), args.out, args.vary, tuple(args.overrides), args.jobs, args.scheduler,
                   tuple(args.plugins), registry, force=args.force)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("compare", help="run variants of a scene side by side and report the differences")
    p.add_argument("cases", nargs="+", type=Path, metavar="CASE",
                   help="case files (one per variant, or one with --vary)")
    p.add_argument("--out", type=Path, required=True, help="report folder; each variant runs into OUT/<label>/")
    p.add_argument("--vary", metavar="KEY=A,B[,C...]",
                   help="one variant per value, each read like a --set value (inline tables too)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a value of every variant")
    executor_options(p)
    force_option(p)
    plugin_options(p)
    p.set_defaults(handler=compare, options=CompareOptions.from_args)


def compare(options: CompareOptions) -> int:
    """``multilayer compare``: 0 all ran, 1 a variant failed, 2 a variant (or --vary, --jobs) is invalid (130, 143
    stopped by SIGINT, SIGTERM: :mod:`multilayer.campaign.executor` stops the runs)."""
    if options.jobs < 1:
        return invalid("compare: invalid command line",
                       [Problem("--jobs", options.jobs, "expected an integer >= 1 (runs at once)")])
    try:
        variants = make_variants(options.cases, options.vary, options.overrides)
    except CaseError as exc:
        return invalid("compare: invalid command line", exc.problems)
    loaded, problems = load_variants(variants, options.registry)
    if problems:
        print(invalid_message("compare", variants, problems), file=sys.stderr)
        return INVALID
    out = options.out
    try:
        open_campaign(out, ("report.json", "report.md", "probes.png", "eta_spacetime.png"), options.force,
                      runs=[v.label for v, _ in loaded])
    except ResultsError as exc:
        print(f"compare: {exc}", file=sys.stderr)
        return INVALID
    variants = [v for v, _ in loaded]  # with the snapshot cadence they ran with
    try:
        runs = run_variants(variants, out, options.registry, options.jobs, options.plugins, options.scheduler)
    except ExecutorError as exc:
        print(f"compare: {exc}", file=sys.stderr)
        return INVALID
    data = write_report(out, variants, runs, options.registry, options.vary)
    failed = [c["label"] for c in data["variants"] if c["status"] != "ok"]
    print(f"report: {out / 'report.md'}")
    if failed:
        print(f"compare: {len(failed)} variant(s) failed: {', '.join(failed)}", file=sys.stderr)
        return FAILED
    return OK
