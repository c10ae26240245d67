"""``multilayer resume DIR``: continue an interrupted or finished run from its checkpoint."""

from __future__ import annotations

import argparse
from pathlib import Path

import attrs

from multilayer.commands.common import plugin_options, run_options
from multilayer.commands.run import run_or_resume
from multilayer.plugin.registry import Registry


@attrs.frozen
class ResumeOptions:
    """``multilayer resume``."""

    out: Path
    until: float | None
    checkpoint_every: int | None  #: None: as the run did
    quiet: bool
    no_plots: bool
    registry: Registry

    @classmethod
    def from_args(cls, args: argparse.Namespace, registry: Registry, command_line: str) -> ResumeOptions:
        return cls(args.out, args.until, args.checkpoint_every, args.quiet, args.no_plots, registry)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("resume", help="continue an interrupted or finished run from its checkpoint")
    p.add_argument("out", type=Path, metavar="DIR", help="the results folder of the run")
    p.add_argument("--until", type=float, metavar="T", help="run to this time (s) instead of the case's end")
    run_options(p, checkpoints=False)
    p.add_argument("--checkpoint-every", type=int, default=None, metavar="N",
                   help="checkpoint every N steps (default: as the run did)")
    plugin_options(p)
    p.set_defaults(handler=resume, options=ResumeOptions.from_args)


def resume(options: ResumeOptions) -> int:
    """``multilayer resume``: the exit codes of ``run``."""
    return run_or_resume(None, options.out, options.registry, quiet=options.quiet, no_plots=options.no_plots,
                         checkpoint_every=options.checkpoint_every, until=options.until)
