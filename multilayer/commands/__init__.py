"""The ``multilayer`` command line: one module per command, exit codes and shared options in one place.

:func:`cli` is the console script.  It imports the commands only once it
has taken SIGINT and SIGTERM over, so that a Ctrl-C or a SIGTERM at any moment, the
imports included, ends the command with one line and exit code 130 or 143
(a run in progress catches both itself and stops cleanly,
:mod:`multilayer.runner.loop`).
"""

from __future__ import annotations

import signal
import sys
from collections.abc import Sequence

from multilayer.plugin.interrupts import on_sigint


class Terminated(BaseException):
    """SIGTERM outside a run (a run catches it itself): the command stops where it is."""


def _terminate(signum: int, frame: object) -> None:
    raise Terminated


def cli(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``multilayer`` console script; returns the exit code (see :mod:`multilayer.commands.main`)."""
    previous = {signal.SIGTERM: signal.signal(signal.SIGTERM, _terminate),
                signal.SIGINT: signal.signal(signal.SIGINT, on_sigint)}
    try:
        from multilayer.commands.main import main as command

        return command(argv)
    except KeyboardInterrupt:
        print("multilayer: interrupted (SIGINT)", file=sys.stderr)
        return 128 + signal.SIGINT
    except Terminated:
        print("multilayer: terminated (SIGTERM)", file=sys.stderr)
        return 128 + signal.SIGTERM
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
