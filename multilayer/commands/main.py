"""The ``multilayer`` command: run, resume, plot, validate, plugins, check-plugin, compare, study, stability, sweep.

Exit codes: 0 ok, 1 a run that failed, 2 an invalid case or plugin set
(the problems on stderr, one per line, without a traceback), 130 stopped
by SIGINT (Ctrl-C), 143 by SIGTERM (one line on stderr; a run finishes its
step and writes its summary first, and so do a campaign's runs in flight); see
:mod:`multilayer.commands.common` and :mod:`multilayer.commands`.

    multilayer validate cases/pulse.toml --set time.dt=5e-5
    multilayer run cases/pulse.toml --out results/pulse
    multilayer plugins --plugin my_layer.py
    multilayer check-plugin my-layer --plugin my_layer.py
    multilayer compare cases/membrane-mode.toml --vary layers[0].tension=2e4,8e4 --out results/tension
    multilayer study cases/pulse-koiter.toml --vary time.dt=1e-4,5e-5,2.5e-5 --out results/dt-study
    multilayer stability cases/pulse-koiter.toml --couplers kinematic-splitting,monolithic --out results/stability
    multilayer sweep cases/pulse-koiter.toml --vary time.dt=1e-4,5e-5 --vary layers[0].young=5e5,1e6 --out results/sweep

Each command is one module of this package that registers itself:
``add_parser(subparsers)`` adds its sub-parser and sets two defaults,
``options`` (``Options.from_args(args, registry, command_line)``, the
command's one ``attrs`` record) and ``handler`` (the function that takes that
record and returns the exit code).  A new command is a new module and one
entry in :data:`COMMANDS`.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from collections.abc import Sequence

from multilayer.commands import (
    check_plugin,
    compare,
    plot,
    plugins,
    resume,
    run,
    stability,
    study,
    sweep,
    validate,
)
from multilayer.commands.common import INVALID
from multilayer.plugin.loading import load_registry
from multilayer.plugin.registry import RegistryError
from multilayer.version import __version__

#: the command modules, in the order ``multilayer --help`` lists them
COMMANDS = (run, resume, plot, validate, plugins, check_plugin, compare, study, stability, sweep)


def build_parser() -> argparse.ArgumentParser:
    """The parser of the ``multilayer`` command line: one sub-parser per module of :data:`COMMANDS`."""
    parser = argparse.ArgumentParser(
        prog="multilayer", description="Fluid–multi-layered-structure interaction from TOML case files."
    )
    parser.add_argument("--version", action="version", version=f"multilayer {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS:
        command.add_parser(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``multilayer`` console script; returns the exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser().parse_args(argv)
    try:
        registry = load_registry(args.plugins)
        return args.handler(args.options(args, registry, shlex.join(["multilayer", *argv])))
    except RegistryError as exc:
        print(f"plugins: {exc}", file=sys.stderr)
        return INVALID
