"""``multilayer validate CASE``: check a case file, report every problem, or summarise the valid case."""

from __future__ import annotations

import argparse
from pathlib import Path

import attrs

from multilayer.campaign.sweep import read_sweep_table
from multilayer.case.casefile import load_case
from multilayer.case.model import Case, TimeSpec
from multilayer.commands.common import OK, case_options, plugin_options
from multilayer.commands.run import invalid_case, warn
from multilayer.plugin.problems import CaseError
from multilayer.plugin.registry import Registry


@attrs.frozen
class ValidateOptions:
    """``multilayer validate``."""

    case: Path
    overrides: tuple[str, ...]
    registry: Registry

    @classmethod
    def from_args(cls, args: argparse.Namespace, registry: Registry, command_line: str) -> ValidateOptions:
        return cls(args.case, tuple(args.overrides), registry)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("validate", help="check a case file and report every problem")
    case_options(p)
    plugin_options(p)
    p.set_defaults(handler=validate, options=ValidateOptions.from_args)


def validate(options: ValidateOptions) -> int:
    """``multilayer validate``: 0 valid (with a summary), 2 invalid (every problem, one per line)."""
    try:
        case = load_case(options.case, options.overrides, options.registry)
    except CaseError as exc:
        return invalid_case(options.case, exc)
    warn(case)
    print(describe(options.case, case))
    describe_sweep(options.case)
    return OK


def describe(path: Path, case: Case) -> str:
    """The summary of a valid case: channel, mesh, time steps, models, digest."""
    layers = ", ".join(f"{layer.model} ({'thin' if layer.thin else 'thick'})" for layer in case.layers) or "none"
    fluid = case.fluid.model if case.fluid is not None else "none"
    g, t = case.geometry, case.time
    return "\n".join([
        f"{path}: valid" + (f" — {case.title}" if case.title else ""),
        f"  channel  L = {g.length:g} cm, R = {g.radius:g} cm; mesh {case.mesh.nz} x {case.mesh.nr}, order {case.mesh.order}",
        f"  time     {time_line(t)}",
        f"  fluid    {fluid}",
        f"  layers   {layers}",
        f"  coupler  {case.coupler.model}",
        f"  digest   {case.digest[:16]}",
    ])


def time_line(t: TimeSpec) -> str:
    """The time steps of a case: fixed, or adaptive with their tolerance, first step, bounds and control.

    >>> time_line(TimeSpec(end=3.0, dt=2e-3))
    '1500 steps of 0.002 s to 3 s'
    >>> time_line(TimeSpec(end=3.0, dt=1e-4, tolerance=1e-3, dt_max=8e-3, control="per-unit-step"))
    'adaptive steps to 3 s: tolerance 0.001 (per-unit-step), first step 0.0001 s, at most 0.008 s'
    >>> time_line(TimeSpec(end=0.012, dt=1e-6, tolerance=1e-2))
    'adaptive steps to 0.012 s: tolerance 0.01 (per-step), first step 1e-06 s'
    """
    if not t.adaptive:
        return f"{t.steps} steps of {t.dt:g} s to {t.end:g} s"
    bounds = "".join([f", at least {t.dt_min:g} s" if t.dt_min is not None else "",
                      f", at most {t.dt_max:g} s" if t.dt_max is not None else ""])
    return (f"adaptive steps to {t.end:g} s: tolerance {t.tolerance:g} ({t.sharing}), "
            f"first step {t.dt:g} s{bounds}")


def describe_sweep(path: Path) -> None:
    """For a case with a (valid) ``[sweep]`` table: how many runs it declares and that ``sweep`` runs them."""
    table = read_sweep_table(path)
    if table is not None:
        print(f"  sweep    {table.size} runs over {', '.join(table.keys)}: 'multilayer sweep' runs them; "
              f"'run' runs the case as written, without [sweep]")
