"""What the commands share: the exit codes, the options several commands take, and how problems are printed.

Exit codes: :data:`OK` 0, :data:`FAILED` 1 a run that failed, :data:`INVALID`
2 an invalid case, command line or plugin set (the problems on stderr, one
per line, without a traceback), :data:`INTERRUPTED` 130 stopped by SIGINT
(Ctrl-C) and :data:`TERMINATED` 143 by SIGTERM, as a shell reports them
(:func:`multilayer.plugin.interrupts.exit_code`), after one line on stderr.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable
from pathlib import Path

from multilayer.plugin.problems import CaseError, Problem

OK, FAILED, INVALID = 0, 1, 2
INTERRUPTED = 130  #: 128 + SIGINT, as a shell reports an interrupted command
TERMINATED = 143  #: 128 + SIGTERM


def case_options(p: argparse.ArgumentParser) -> None:
    """The case file and its ``--set`` overrides, of the commands that read one case."""
    p.add_argument("case", type=Path, help="the TOML case file")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a value of the case, e.g. time.dt=5e-5 or layers[0].young=1e6")


def plugin_options(p: argparse.ArgumentParser) -> None:
    """``--plugin``, of every command: :func:`multilayer.commands.main.main` loads them before the command runs."""
    p.add_argument("--plugin", dest="plugins", action="append", default=[], metavar="MODULE",
                   help="also load plugins from this module (dotted name or .py file)")


def run_options(p: argparse.ArgumentParser, checkpoints: bool = True) -> None:
    """The options of commands that run a case."""
    if checkpoints:
        p.add_argument("--checkpoint-every", type=int, default=0, metavar="N",
                       help="write the whole state every N steps (and when interrupted), for 'multilayer resume'")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary at the end")
    p.add_argument("--no-plots", action="store_true", help="do not draw the run's figures at the end")


def force_option(p: argparse.ArgumentParser) -> None:
    """``--force``: write into a folder a new run refuses by default (see :class:`multilayer.results.folder.ResultsFolder`)."""
    p.add_argument("--force", action="store_true",
                   help="write into --out even when it is the current directory, your home folder, or a non-empty "
                        "folder that is not a results folder (the run still touches only the files it writes)")


def executor_options(p: argparse.ArgumentParser, jobs: int | None = 1, jobs_help: str = "") -> None:
    """``--jobs`` and ``--scheduler`` of the commands that run many cases (:mod:`multilayer.campaign.executor`)."""
    p.add_argument("--jobs", type=int, default=jobs, metavar="N",
                   help=jobs_help or "runs at once: 1 runs them here one after the other, more on a local Dask "
                                     "cluster of N worker processes (a process pool without Dask)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on an existing Dask cluster, e.g. tcp://host:8786 (needs the extra 'dask'; "
                        "case files and --out on a file system the workers share)")


def invalid(head: str, problems: Iterable[Problem]) -> int:
    """Print ``head`` and then one line per problem on stderr; the exit code :data:`INVALID`.

    >>> import contextlib, io
    >>> with contextlib.redirect_stderr(io.StringIO()) as err:
    ...     code = invalid("study: invalid command line", [Problem("--jobs", 0, "expected an integer >= 1")])
    >>> code, err.getvalue()
    (2, 'study: invalid command line\\n--jobs = 0: expected an integer >= 1\\n')
    """
    print(head, file=sys.stderr)
    print(str(CaseError(problems)), file=sys.stderr)
    return INVALID
