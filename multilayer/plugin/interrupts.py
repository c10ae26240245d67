"""The command line's SIGINT and SIGTERM: the exceptions they raise, told apart from what a plugin raises.

The ``multilayer`` command takes both signals over before it imports
anything heavy (:func:`multilayer.commands.console`): from then on a SIGINT
raises :class:`UserInterrupt` and a SIGTERM :class:`Terminated` wherever the
command is (:class:`CommandSignals`), and the command ends with one line and
exit code 128 + the signal (:func:`exit_code`: 130, 143).  A run catches both
itself and stops after its step (:mod:`multilayer.runner.loop`).

Loading plugins reports anything a plugin module raises while imported,
``KeyboardInterrupt`` included, as a plugin that cannot be loaded
(:func:`multilayer.plugin.registry.import_failure`); :class:`UserInterrupt`
is let through, and :class:`Terminated` is neither an ``Exception`` nor a
``KeyboardInterrupt``, so a signal while plugins load stops the command.
"""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager


class UserInterrupt(KeyboardInterrupt):
    """SIGINT, delivered to the process (Ctrl-C): not a plugin's doing."""


class Terminated(BaseException):
    """SIGTERM, delivered to the process: the command stops where it is."""


#: the signals the command line takes over, in the order it installs their handlers, with the exception each raises
#: (SIGTERM last: once ``/proc/PID/status`` shows it caught, both handlers are the command line's)
EXCEPTIONS = {"SIGINT": UserInterrupt, "SIGTERM": Terminated}


def stopped(name: str) -> BaseException:
    """The exception the command line's handler raises for the signal ``name``.

    Raised again by whoever ran a run that caught the signal itself and
    returned: the command the run was part of stops too.

    >>> type(stopped("SIGINT")).__name__, type(stopped("SIGTERM")).__name__
    ('UserInterrupt', 'Terminated')
    """
    return EXCEPTIONS[name]()


def signal_name(exc: BaseException) -> str | None:
    """The signal behind ``exc`` (``SIGINT`` for any ``KeyboardInterrupt``), None for another exception.

    >>> signal_name(UserInterrupt()), signal_name(KeyboardInterrupt()), signal_name(Terminated()), signal_name(OSError())
    ('SIGINT', 'SIGINT', 'SIGTERM', None)
    """
    if isinstance(exc, KeyboardInterrupt):
        return "SIGINT"
    if isinstance(exc, Terminated):
        return "SIGTERM"
    return None


def exit_code(name: str) -> int:
    """The exit code of a command a signal stopped, as a shell reports it: 128 + the signal's number.

    >>> exit_code("SIGINT"), exit_code("SIGTERM")
    (130, 143)
    """
    return 128 + signal.Signals[name].value


class CommandSignals:
    """The command line's handler of SIGINT and SIGTERM: records each signal, then raises its exception.

    Recorded first, so that a signal whose exception some library swallows
    (an ``except BaseException`` that does not raise again) still ends the
    command with its exit code when it returns.  Once the command ends
    (:meth:`ending`), a signal is only recorded: the handler is never the
    cause of a traceback in the command's last lines.
    """

    def __init__(self) -> None:
        self.received: list[str] = []  #: the names of the signals received, in order
        self.raising = True
        self.answered = False  #: the command ended as the first of them asks (its line printed, 128 + the signal)

    def __call__(self, signum: int, frame: object) -> None:
        name = signal.Signals(signum).name
        self.received.append(name)
        if self.raising:
            raise stopped(name)

    def install(self) -> dict[signal.Signals, object]:
        """Install this handler for SIGINT, then SIGTERM; the handlers it replaces, by signal."""
        return {signal.Signals[name]: signal.signal(signal.Signals[name], self) for name in EXCEPTIONS}

    def ending(self) -> None:
        """From now on only record the signals (the command is ending, with its exit code)."""
        self.raising = False


@contextmanager
def deferred() -> Iterator[None]:
    """Hold the command line's SIGINT and SIGTERM back for the block: one that arrives meanwhile is raised at its
    end, once the block is done.

    For a few seconds' work that an exception would leave half done (a Dask
    cluster half started, whose close at exit fails with a traceback).  When
    the block fails after a signal, the signal is raised instead of its
    failure (the signal is the cause: it ended a process the block started).
    Outside the command line (another handler installed) nothing changes.
    """
    handler = signal.getsignal(signal.SIGTERM)
    if not isinstance(handler, CommandSignals) or not handler.raising:
        yield
        return
    before = len(handler.received)
    handler.raising = False
    try:
        yield
    except BaseException:
        handler.raising = True
        if len(handler.received) > before:  # the signal, not what it made fail (a worker it ended), stops the command
            raise stopped(handler.received[before]) from None
        raise
    handler.raising = True
    if len(handler.received) > before:
        raise stopped(handler.received[before])
