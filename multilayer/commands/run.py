"""``multilayer run CASE --out DIR``: run a case, writing its results folder (and its figures)."""

from __future__ import annotations

import argparse
import sys
import time
import traceback
from pathlib import Path

import attrs

from multilayer.case.casefile import load_case
from multilayer.case.model import Case
from multilayer.commands.common import (
    FAILED,
    INVALID,
    OK,
    case_options,
    force_option,
    plugin_options,
    run_options,
)
from multilayer.commands.plot import plot_folder
from multilayer.plugin.interrupts import exit_code
from multilayer.plugin.problems import CaseError
from multilayer.plugin.registry import Registry
from multilayer.results.folder import ResultsError
from multilayer.runner import checkpoint, loop, progress
from multilayer.runner.checkpoint import CheckpointError


@attrs.frozen
class RunOptions:
    """``multilayer run``."""

    case: Path
    out: Path | None  #: None: ``--out ''``
    overrides: tuple[str, ...]
    checkpoint_every: int
    quiet: bool
    no_plots: bool
    registry: Registry
    force: bool = False

    @classmethod
    def from_args(cls, args: argparse.Namespace, registry: Registry, command_line: str) -> RunOptions:
        out = Path(args.out) if args.out.strip() else None
        return cls(args.case, out, tuple(args.overrides), args.checkpoint_every, args.quiet, args.no_plots,
                   registry, args.force)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("run", help="run a case, writing results to a folder")
    case_options(p)
    plugin_options(p)
    p.add_argument("--out", required=True,
                   help="results folder (created; a run writes, replaces and removes only its own files there)")
    force_option(p)
    run_options(p)
    p.set_defaults(handler=run, options=RunOptions.from_args)


def run(options: RunOptions) -> int:
    """``multilayer run``: 0 the run ended ok, 1 it failed, 2 an invalid case or option, 130 interrupted by SIGINT
    (Ctrl-C), 143 by SIGTERM."""
    if options.out is None:
        print("run: --out is empty: name the results folder", file=sys.stderr)
        return INVALID
    try:
        case = load_case(options.case, options.overrides, options.registry)
    except CaseError as exc:
        return invalid_case(options.case, exc)
    warn(case)
    if options.checkpoint_every < 0:
        print(f"--checkpoint-every = {options.checkpoint_every}: expected a whole number of steps >= 0",
              file=sys.stderr)
        return INVALID
    return run_or_resume(case, options.out, options.registry, quiet=options.quiet, no_plots=options.no_plots,
                         checkpoint_every=options.checkpoint_every, force=options.force)


def warn(case: Case) -> None:
    """What validation found odd in ``case`` (``case.warnings``: a plain number implausible in its unit), on
    stderr, one line each."""
    for warning in case.warnings:
        print(f"warning: {warning}", file=sys.stderr)


def invalid_case(path: Path, error: CaseError) -> int:
    """Say that the case file ``path`` is invalid, and why (stderr); the exit code :data:`INVALID`."""
    print(f"{path}: invalid case", file=sys.stderr)
    print(str(error), file=sys.stderr)
    return INVALID


def run_or_resume(case: Case | None, out: Path, registry: Registry, *, quiet: bool, no_plots: bool,
                  checkpoint_every: int | None, until: float | None = None, force: bool = False) -> int:
    """``run`` (a case) or ``resume`` (``case`` None: the folder's checkpoint, to ``until``): the exit code.

    A progress bar while it runs (unless ``quiet``), the figures at the end
    (unless ``no_plots``), then the summary.  ``force``: a run may write into
    a folder it refuses by default (:class:`~multilayer.results.folder.ResultsFolder`).
    """
    try:
        is_file = out.exists() and not out.is_dir()
    except (OSError, RuntimeError):  # a name too long, a link loop: the results folder refuses it, saying why
        is_file = False
    if is_file:
        print(f"--out {out} is a file, not a folder", file=sys.stderr)
        return INVALID
    t0 = time.perf_counter()
    bar = None
    try:  # loop.run_case, progress.ProgressBar: looked up at each run (tests replace them)
        if case is not None:
            bar = progress.ProgressBar(case.time.end, enabled=None if not quiet else False)
            result = loop.run_case(case, out, registry, checkpoint_every=checkpoint_every, progress=bar,
                                   **({"force": True} if force else {}))
        else:
            saved = checkpoint.load(out, registry, until)
            bar = progress.ProgressBar(saved.case.time.end, saved.tally.t, enabled=None if not quiet else False,
                                       step=saved.tally.steps)
            result = loop.resume_run(out, until, registry, checkpoint_every=checkpoint_every, progress=bar,
                                     saved=saved)
    except (ResultsError, CheckpointError) as exc:
        print(f"{'run' if case is not None else 'resume'}: {exc}", file=sys.stderr)
        return INVALID
    except loop.Interrupted as exc:  # before the folder was touched (a resume's setup)
        print(f"resume: interrupted by {exc} while setting up; {out} is as it was", file=sys.stderr)
        return exit_code(str(exc))
    except Exception:  # a bug, not a user mistake: the traceback helps
        traceback.print_exc()
        print(f"run failed; partial results in {out}", file=sys.stderr)
        return FAILED
    finally:
        if bar is not None:
            bar.close()
    if not no_plots and result.steps:
        plot_folder(out, quiet=True)
    if not quiet:
        print(progress.summary(result, time.perf_counter() - t0, out, checkpoint=checkpoint.exists(out)))
    if result.status == "interrupted":
        print(f"{'run' if case is not None else 'resume'}: {result.reason}; the results so far are in {out}"
              + (f", continue with: multilayer resume {out}" if checkpoint.exists(out) else ""), file=sys.stderr)
        return exit_code(result.signal)
    if result.status != "ok":
        print(f"run failed: {result.reason}", file=sys.stderr)
        return FAILED
    return OK
