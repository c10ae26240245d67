"""``multilayer stability``: couplers × wall-to-fluid mass ratio ρ₁h/(ρ_f R) (× time steps), in one map.

The grid is :mod:`multilayer.campaign.planning`'s, the ratios and measurements
:mod:`multilayer.campaign.stability`'s, the report
:mod:`multilayer.campaign.stability_report`'s; see ``docs/stability.md``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import attrs

from multilayer.campaign import stability_report
from multilayer.campaign.executor import ExecutorError
from multilayer.campaign.planning import (
    grid_options,
    invalid_runs,
    plan_grid,
    run_planned,
)
from multilayer.campaign.stability import (
    DEFAULT_RATIOS,
    Ratios,
    layer_problems,
    map_data,
    parse_ratios,
    vary_problems,
)
from multilayer.campaign.variants import invalid_message
from multilayer.case.casefile import load_case
from multilayer.case.grid import vary_axis
from multilayer.commands.common import (
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
class StabilityOptions:
    """``multilayer stability``."""

    case: Path
    out: Path  #: the map's folder; runs go to ``OUT/<coupler>/ratio=<r>/<key=value>/``
    couplers: str | None  #: ``--couplers`` (:func:`multilayer.campaign.planning.parse_couplers`); None: the case's own
    ratios: str | None  #: ``--ratios``, values of ρ₁h/(ρ_f R); None: :data:`~multilayer.campaign.stability.DEFAULT_RATIOS`
    varies: tuple[str, ...]  #: every ``--vary KEY=A,B,...``
    layer: int  #: the thin layer whose density realises the ratio
    overrides: tuple[str, ...]  #: ``--set``, before the coupler, the density and the varied values
    jobs: int
    scheduler: str | None
    plugins: tuple[str, ...]  #: ``--plugin`` modules, loaded again by every worker
    registry: Registry
    command_line: str  #: written at the top of ``stability.md``
    force: bool = False  #: write into a folder refused by default (see results.campaign)

    @classmethod
    def from_args(cls, args: argparse.Namespace, registry: Registry, command_line: str) -> StabilityOptions:
        return cls(args.case, args.out, args.couplers, args.ratios, tuple(args.varies), args.layer,
                   tuple(args.overrides), args.jobs, args.scheduler, tuple(args.plugins), registry, command_line, force=args.force)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("stability", help="stability map: couplers x wall-to-fluid mass ratio "
                                                "rho1*h/(rho_f*R) (x time steps)")
    case_options(p)
    plugin_options(p)
    p.add_argument("--out", type=Path, required=True,
                   help="map folder; each run goes into OUT/<coupler>/ratio=<r>/<key=value>/")
    p.add_argument("--couplers", metavar="A,B,...",
                   help="coupler names or inline tables replacing [coupler] (default: the case's own)")
    p.add_argument("--ratios", metavar="R1,R2,...",
                   help="values of rho1*h/(rho_f*R), set through the thin layer's density "
                        "(default: 1,0.1,0.01,0.001)")
    p.add_argument("--layer", type=int, default=0, metavar="L",
                   help="the thin layer whose density sets the ratio (default: 0)")
    p.add_argument("--vary", dest="varies", action="append", default=[], metavar="KEY=A,B[,C...]",
                   help="values of a key, e.g. time.dt=1e-4,1e-5 (repeatable: one map per combination)")
    executor_options(p)
    force_option(p)
    p.set_defaults(handler=stability, options=StabilityOptions.from_args)


def stability(options: StabilityOptions) -> int:
    """``multilayer stability``: 0 the map is made (failed runs are results), 2 invalid input (130, 143 stopped by
    SIGINT, SIGTERM: :mod:`multilayer.campaign.executor` stops the runs)."""
    o = options
    try:
        choices, axes, problems = grid_options(o.case, o.out, o.couplers, o.varies, o.jobs, o.overrides, o.registry)
        case = load_case(o.case, o.overrides, o.registry)
    except CaseError as exc:
        return invalid(f"{o.case}: invalid case", exc.problems)
    try:
        values = parse_ratios(DEFAULT_RATIOS if o.ratios is None else o.ratios)
    except CaseError as exc:
        problems += exc.problems
    problems += layer_problems(case, o.layer) + vary_problems(axes, o.layer)
    if problems:
        return invalid("stability: invalid command line", problems)
    realised = Ratios.of(case, o.layer, values)
    planned = plan_grid(o.case, choices, [realised.axis(), *(vary_axis(k, v) for k, v in axes)], o.overrides)
    variants = [p.variant for p in planned]
    wrong = invalid_runs(variants, o.registry)
    if wrong:
        print(invalid_message("stability", variants, wrong, "runs"), file=sys.stderr)
        return INVALID
    try:
        open_campaign(o.out, ("stability.json", "stability.md", "stability.png"), o.force,
                      runs=[p.folder for p in planned])
    except ResultsError as exc:
        print(f"stability: {exc}", file=sys.stderr)
        return INVALID
    folders = {p.label: o.out / p.folder for p in planned}
    try:
        runs = run_planned(variants, folders, o.jobs, o.registry, o.plugins, o.scheduler)
    except ExecutorError as exc:
        print(f"stability: {exc}", file=sys.stderr)
        return INVALID
    data = map_data(planned, runs, realised, choices, axes, command=o.command_line, case_file=o.case,
                    title=case.title, overrides=o.overrides)
    stability_report.write(o.out, data)
    stable = sum(r["stable"] for r in data["runs"])
    print(f"map: {o.out / 'stability.md'} ({stable} of {len(data['runs'])} runs stable)")
    return OK
