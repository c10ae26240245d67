"""The ``multilayer`` command line: one module per command, exit codes and shared options in one place.

:func:`console` is the console script, :func:`cli` the same command run in
a process that is not its own (a test, a notebook).  Both take SIGINT and
SIGTERM over before they import the commands, so that a Ctrl-C or a
SIGTERM at any moment, the imports included, ends the command with one line
and exit code 130 or 143 (a run in progress catches both itself, finishes
its step and stops cleanly, :mod:`multilayer.runner.loop`; so do a
campaign's runs, :mod:`multilayer.campaign.executor`).  This package's
``__init__`` modules and :mod:`multilayer.plugin.interrupts` import only a
few modules of the standard library, so the console script takes the
signals over a few milliseconds after Python has started; before, Python
answers them itself.
"""

from __future__ import annotations

import atexit
import signal
import sys
from collections.abc import Sequence

from multilayer.plugin.interrupts import (
    EXCEPTIONS,
    CommandSignals,
    Terminated,
    exit_code,
    signal_name,
)


def _stopped_by(name: str, signals: CommandSignals) -> int:
    signals.answered = True
    print(f"multilayer: {'interrupted' if name == 'SIGINT' else 'terminated'} ({name})", file=sys.stderr)
    return exit_code(name)


def _command(argv: Sequence[str] | None, signals: CommandSignals) -> int:
    """Import the commands and run ``argv``, ``signals`` installed: the exit code (128 + a signal that stopped it)."""
    try:
        try:
            from multilayer.commands.main import main as command

            code = command(argv)
        finally:
            signals.ending()
    except (KeyboardInterrupt, Terminated) as exc:
        return _stopped_by(signal_name(exc), signals)
    except Exception:
        # the signal's exception, turned into another on its way: an extension module (Cython, Pythran) whose
        # import it stopped raises "ImportError: initialization failed" instead
        if signals.received:
            return _stopped_by(signals.received[0], signals)
        raise
    if signals.received:  # its exception was swallowed on the way (an ``except BaseException`` that did not raise)
        return _stopped_by(signals.received[0], signals)
    return code


def cli(argv: Sequence[str] | None = None) -> int:
    """Run the ``multilayer`` command ``argv`` (default ``sys.argv[1:]``) here; returns the exit code.

    SIGINT and SIGTERM are the command's while it runs (see
    :mod:`multilayer.commands.main` for the exit codes); their handlers are
    given back after.
    """
    signals = CommandSignals()
    previous = signals.install()
    try:
        return _command(argv, signals)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def console() -> int:
    """The console script ``multilayer``: :func:`cli` in a process of its own; returns the exit code.

    Its first statement takes SIGINT and SIGTERM over.  A command that
    SIGINT stopped ends the process by SIGINT itself, as Python does with a
    KeyboardInterrupt nobody caught, once everything else has ended (the last
    ``atexit`` function): a shell reports 130 as for any exit with 130, and a
    shell loop (``for c in *.toml; do multilayer run ...; done``) stops on
    Ctrl-C, which it does not when the command exits with 130 (bash takes an
    exit code for a signal the command handled and goes on).  SIGTERM
    has no such convention: the exit code 143.

    Once the command has returned, both signals get their default actions
    back instead of Python's handlers (whose KeyboardInterrupt would end the
    interpreter's shutdown, a fifth of a second with the plotting library
    loaded, with a traceback): a signal then ends the process at once, its
    work done and written, without a line; a shell reports 130 or 143.
    """
    signals = CommandSignals()
    signals.install()
    end_by: list[signal.Signals] = []
    atexit.register(lambda: end_by and _end_by(end_by[0]))  # registered first: called last
    code = _command(None, signals)
    for name in EXCEPTIONS:
        signal.signal(signal.Signals[name], signal.SIG_DFL)
    if signals.received and not signals.answered:  # it came after the command had returned: the default action
        _end_by(signal.Signals[signals.received[0]])
    if code == exit_code("SIGINT"):
        end_by.append(signal.SIGINT)
    return code


def _end_by(sig: signal.Signals) -> None:
    """End this process by the signal ``sig``'s default action, what it printed flushed first."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a pipe closed by its reader, a stream closed
            pass
    signal.signal(sig, signal.SIG_DFL)
    signal.raise_signal(sig)
