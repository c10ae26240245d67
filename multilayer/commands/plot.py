"""``multilayer plot DIR``: draw the figures of a results folder (:func:`multilayer.results.figures.plot_run`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import attrs

from multilayer.commands.common import FAILED, INVALID, OK, plugin_options
from multilayer.plugin.registry import Registry


@attrs.frozen
class PlotOptions:
    """``multilayer plot``."""

    out: Path

    @classmethod
    def from_args(cls, args: argparse.Namespace, registry: Registry, command_line: str) -> PlotOptions:
        return cls(args.out)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("plot", help="draw the figures of a results folder")
    p.add_argument("out", type=Path, metavar="DIR", help="the results folder of a run")
    plugin_options(p)
    p.set_defaults(handler=plot, options=PlotOptions.from_args)


def plot(options: PlotOptions) -> int:
    """``multilayer plot``: 0 drawn, 1 a figure could not be drawn, 2 not a results folder."""
    return plot_folder(options.out)


def plot_folder(out: Path, quiet: bool = False) -> int:
    """Draw the figures of the results folder ``out``, listing them unless ``quiet``: the exit code."""
    # matplotlib is heavy (results.figures loads it): imported only when figures are drawn
    from multilayer.results.figures import plot_run

    if not (out / "summary.json").is_file():
        print(f"plot: {out} is not a results folder (no summary.json)", file=sys.stderr)
        return INVALID
    try:
        written = plot_run(out)
    except Exception as exc:  # a figure is a by-product: say so, keep the run's status
        print(f"plot: the figures of {out} could not be drawn ({type(exc).__name__}: {exc})", file=sys.stderr)
        return FAILED
    if not quiet:
        print("\n".join(str(p) for p in written) or f"plot: nothing to draw in {out}")
    return OK
