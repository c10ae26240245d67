"""Running a case: build the setup, let the coupler advance the state, close the ledger, write everything.

The results folder is a contract other tools rely on:

* ``summary.json`` — status (``ok``, ``failed`` with a ``reason``, or
  ``interrupted``), the resolved case and its hash, plugin versions, DOF
  counts, steps, wall time, per-phase timings, the energy ledger's largest
  relative residual, sub-iterations when the coupler reports them;
* ``series.csv`` — one row per step: ``t``, every ledger term, every probe;
* ``eta_lumen.csv`` — η on the lumen line at every vertex, every step (when there is a wall);
* ``wss_lumen.csv`` — the wall shear stress τ_w at the same vertices, every step (when there is a fluid);
* ``<part>_NNNNNN.vtu`` + ``<part>.pvd`` — field snapshots for ParaView (``wall``, ``fluid``, and ``lumen``:
  the lumen with τ_w);
* ``checkpoint.json`` + ``checkpoint.npz`` — the whole state every ``checkpoint_every`` steps, as data
  (:mod:`multilayer.runner.checkpoint`), for :func:`resume_run`.

A run that fails (a non-finite value, a collapsing wall, energy beyond
the work put in) or is interrupted (SIGINT, SIGTERM) stops cleanly and keeps
every row and snapshot written so far.
"""

from __future__ import annotations

import math
import os
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

import attrs
import numpy as np

from multilayer.case.model import Case
from multilayer.coupling import clock
from multilayer.coupling.build import prepare
from multilayer.coupling.contract import Coupler, SchemeFailure
from multilayer.numerics.threads import blas_threads
from multilayer.plugin.registry import Registry, plugin_versions
from multilayer.results.files import open_nofollow
from multilayer.results.folder import ResultsError, ResultsFolder
from multilayer.results.reading import position_column, read_series
from multilayer.results.readouts import probe_ranges
from multilayer.runner import checkpoint
from multilayer.runner.held import HeldResults
from multilayer.runner.readouts import readouts
from multilayer.runner.stepping import (
    EnergyBound,
    RunFailed,
    Step,
    Tally,
    check_state,
    iterate_steps,
    setting_up,
)
from multilayer.scene.setup import Setup
from multilayer.scene.state import State
from multilayer.version import __version__

__all__ = ["EnergyBound", "Interrupted", "RunFailed", "RunResult", "Signals", "Tally", "check_state", "interruptible",
           "resume_run", "run_case", "run_held", "runs", "stop"]


def _snapshot(setup: Setup, state: State, results: ResultsFolder | HeldResults) -> None:
    if setup.wall is not None:
        pts, cells, data = setup.wall_snapshot(state)
        results.snapshot("wall", pts, cells, data, state.t, state.n)
    if setup.fluid is not None:
        pts, cells, data = setup.fluid_snapshot(state)
        results.snapshot("fluid", pts, cells, data, state.t, state.n)
    if setup.gives_wall_shear:
        pts, cells, data = setup.lumen_snapshot(state)
        results.snapshot("lumen", pts, cells, data, state.t, state.n)


@attrs.frozen
class RunResult:
    status: str
    reason: str = ""
    out: Path | None = None
    steps: int = 0
    max_relative_residual: float = 0.0
    t: float = 0.0
    peaks: dict = attrs.field(factory=dict)  #: max |value| of every η probe (cm)
    #: the volume ledger's drift over the volume moved (None without a fluid)
    volume_drift: float | None = None
    #: the signal that stopped an interrupted run (``SIGINT``, ``SIGTERM``; the one its ``reason`` names, also when
    #: :func:`stop` gave it); empty for a run that was not interrupted
    signal: str = ""
    #: every probe's range over the run (summary.json ``probe_ranges``: CGS, pressures in mmHg too)
    ranges: dict = attrs.field(factory=dict)
    #: the summary's ``cycles`` block (with a periodic load; None without)
    cycles: dict | None = None


class Interrupted(Exception):
    """SIGINT or SIGTERM: the run stops after the current step."""


class Signals:
    """The SIGINT and SIGTERM a run has caught (or :func:`stop` gave it); call it for the first one's name (or None).

    A first signal lets the current step finish.  A second SIGINT abandons
    the step, unless it comes while the run writes its files (:meth:`writing`)
    or its summary (:attr:`finishing`): the run is stopping at the end of
    this step anyway, and a write cut short would leave the folder
    inconsistent (every file ends on the same step, the summary says what happened).
    """

    def __init__(self) -> None:
        self.caught: list[str] = []
        self._writing = 0
        self.finishing = False  #: the summary is being written: further signals are only counted

    def __call__(self) -> str | None:
        return self.caught[0] if self.caught else None

    def handler(self, signum: int, frame: object) -> None:
        name = signal.Signals(signum).name
        if self.caught and signum == signal.SIGINT and not self._writing and not self.finishing:
            raise Interrupted(name)
        self.caught.append(name)

    @contextmanager
    def writing(self) -> Iterator[None]:
        """A write no second SIGINT cuts short (the run stops after the step it writes)."""
        self._writing += 1
        try:
            yield
        finally:
            self._writing -= 1


#: the :class:`Signals` of every run going on in this process, by the thread that runs it (see :func:`stop`)
_RUNS: dict[int, Signals] = {}


@contextmanager
def interruptible() -> Iterator[Signals]:
    """Catch SIGINT and SIGTERM while a run goes on; yields the :class:`Signals` caught.

    Installed before the results folder is made and kept until its summary
    is written, so a signal at any moment of a run is caught.  Handlers are
    installed only in the main thread; a run in another thread (a Dask
    worker's) catches no signal, and whoever runs it stops it with :func:`stop`.
    """
    signals = Signals()
    thread = threading.get_ident()
    outer = _RUNS.get(thread)  # a run started by a run's progress callback: the outer one goes on after
    _RUNS[thread] = signals
    try:
        if threading.current_thread() is not threading.main_thread():
            yield signals
            return
        old = {sig: signal.signal(sig, signals.handler) for sig in (signal.SIGINT, signal.SIGTERM)}
        try:
            yield signals
        finally:
            for sig, h in old.items():
                signal.signal(sig, h)
    finally:
        if outer is None:
            del _RUNS[thread]
        else:
            _RUNS[thread] = outer


def stop(name: str, thread: int | None = None) -> list[int]:
    """Stop the run that the thread ``thread`` (its ``threading.get_ident()``) of this process runs, or every run
    of this process, as the signal ``name`` (``SIGINT``, ``SIGTERM``) would: it finishes its step and stops,
    ``interrupted``.  The threads whose runs were told.

    Meant for a run in a thread other than the main one, which catches no signal itself (a Dask worker's:
    :mod:`multilayer.campaign.dask_worker`).  Any thread may call it.
    """
    told = [t for t in list(_RUNS) if thread is None or t == thread]
    for t in told:
        signals = _RUNS.get(t)
        if signals is not None:
            signals.caught.append(name)
    return told


def runs() -> list[int]:
    """The threads of this process that run a run now (see :func:`stop`)."""
    return list(_RUNS)


def run_case(case: Case, out: str | Path, registry: Registry | None = None, *, checkpoint_every: int = 0,
             progress: Callable[[Tally, dict], None] | None = None, force: bool = False) -> RunResult:
    """Run ``case`` and write its results folder ``out``.

    The coupler advances states; this loop closes the energy ledger of each
    step from the terms the coupler reports ([theory](docs/theory.md) §7),
    evaluates the probes and writes rows and snapshots; with
    ``checkpoint_every`` > 0 it writes a checkpoint (``checkpoint.json`` and
    ``checkpoint.npz``) every so many steps and when interrupted.
    ``progress(tally, row)`` is called after every step.  Returns the :class:`RunResult`; the same status is
    in ``summary.json``.  ``force``: ``out`` may be a folder :class:`ResultsFolder` refuses by default; an
    earlier run's files there (its checkpoint included) are removed first, nothing else.
    """
    registry = registry or Registry.load()
    with interruptible() as signals:
        with signals.writing():  # a signal meanwhile: the run stops before its first step
            results = ResultsFolder(out, force=force)
        with blas_threads(case.threads):
            return _run(case, results, registry, None, checkpoint_every, progress, signals)


def run_held(case: Case, registry: Registry | None = None, *,
             progress: Callable[[Tally, dict], None] | None = None) -> tuple[RunResult, HeldResults]:
    """Run ``case`` as :func:`run_case` does, its rows and summary held in memory instead of a folder.

    No file is written (no snapshots, no checkpoints).  Returns the
    :class:`RunResult` and the :class:`~multilayer.runner.held.HeldResults`
    (``tables["series.csv"]``, ``tables["eta_lumen.csv"]``, ``summary``).
    """
    registry = registry or Registry.load()
    held = HeldResults()
    with interruptible() as signals, blas_threads(case.threads):
        return _run(case, held, registry, None, 0, progress, signals), held


def resume_run(out: str | Path, until: float | None = None, registry: Registry | None = None, *,
               checkpoint_every: int | None = None,
               progress: Callable[[Tally, dict], None] | None = None,
               saved: checkpoint.Checkpoint | None = None) -> RunResult:
    """Continue the run of the results folder ``out`` from its checkpoint (to ``until`` s if given).

    The state and every reusing solver's held state are rebuilt from the
    checkpoint's data; rows and snapshots written after it are dropped, so a
    run resumed from step n writes the same files, bit for bit, as one never stopped.
    Raises :class:`checkpoint.CheckpointError` when there is no usable
    checkpoint (before the folder is touched), or the plugins or the case
    differ from the checkpoint's.  ``saved``: the checkpoint as
    :func:`checkpoint.load` read it (for ``out`` and ``until``) when the caller
    has read it already, so that its case is validated once (a prestressed
    wall's reference found once).
    """
    registry = registry or Registry.load()
    if saved is None:
        saved = checkpoint.load(Path(out), registry, until)
    every = saved.checkpoint_every if checkpoint_every is None else checkpoint_every
    with interruptible() as signals, blas_threads(getattr(saved.case, "threads", 1)):
        try:
            with setting_up():
                setup, coupler = prepare(saved.case, registry)
        except RunFailed as exc:
            raise checkpoint.CheckpointError(f"the checkpoint's case cannot be set up here: {exc}") from None
        state = checkpoint.restore(saved, setup, coupler)
        with signals.writing():
            results = ResultsFolder(Path(out), fresh=False)
        return _run(saved.case, results, registry, saved, every, progress, signals, (setup, coupler, state))


def _run(case: Case, results: ResultsFolder | HeldResults, registry: Registry, saved: checkpoint.Checkpoint | None,
         checkpoint_every: int, progress, signals: Signals, prepared: tuple | None = None) -> RunResult:
    wall_t0 = time.perf_counter()
    status, reason, crash, stopped_by = "ok", "", "", ""
    setup: Setup | None = None
    coupler: Coupler | None = None
    tally: Tally | None = saved.tally if saved is not None else None
    resumed_from = saved.tally.steps if saved is not None else None
    try:
        if signals():  # caught while the folder was made
            raise Interrupted(signals())
        if prepared is not None:  # a resumed run: set up, its state rebuilt from the checkpoint
            setup, coupler, state = prepared
        else:
            with setting_up():
                setup, coupler = prepare(case, registry)
                state = coupler.initial_state(setup)
        if tally is None:
            tally = Tally.start(setup, coupler, state)
        tally.clock = state.extra.get("clock")
        probes = setup.probe_rows(case.output.probes)
        with signals.writing():
            writers = Writers(results, setup, saved, ["step", "t", *coupler.energy(setup, state),
                                                      "energy.total", "energy.residual", "energy.relative_residual",
                                                      *probes], signals)
            t_out = time.perf_counter()
            if writers.every and saved is None:
                _snapshot(setup, state, results)
            setup.timings["output"] += time.perf_counter() - t_out
        for step in iterate_steps(setup, coupler, state, tally, probes, writers):
            if progress is not None:
                progress(tally, step.row)
            if checkpoint_every and (step.n % checkpoint_every == 0 or signals()):
                with signals.writing():
                    checkpoint.save(results.path, case, registry, step.state, tally, results.snapshots,
                                    checkpoint_every, time.perf_counter() - wall_t0, setup,
                                    getattr(results, "run_id", None))
            if signals():
                raise Interrupted(signals())
    except Interrupted as exc:
        status, stopped_by = "interrupted", str(exc)
        reason = f"interrupted by {exc} after step {tally.steps if tally else 0} (t = {tally.t if tally else 0:.6g} s)"
    except (RunFailed, SchemeFailure) as exc:
        status, reason = "failed", str(exc)
    except ResultsError as exc:
        status, reason = "failed", f"{exc} (after step {tally.steps if tally else 0})"
    except OSError as exc:  # a full disk, a file system gone: what could not be written, and when
        where = f" {exc.filename}" if exc.filename else ""
        status = "failed"
        reason = (f"cannot write{where}: {exc.strerror or exc} (after step {tally.steps if tally else 0}, "
                  f"t = {tally.t if tally else 0:.6g} s)")
    except (FloatingPointError, np.linalg.LinAlgError, RuntimeError, ValueError) as exc:
        status, reason = "failed", f"{type(exc).__name__} after step {tally.steps if tally else 0}: {exc}"
    except Exception as exc:  # a bug: still keep the results and say where
        status, reason = "failed", f"{type(exc).__name__} after step {tally.steps if tally else 0}: {exc}"
        crash = traceback.format_exc()
        if not signals():
            print(crash, file=sys.stderr)
    if status == "failed" and signals():
        # a signal caught meanwhile stopped it: its effect surfaced as another exception on the way (a C++
        # extension's call cut short reports "Caught an unknown exception!", an import cut short an ImportError)
        status, stopped_by, crash = "interrupted", signals(), ""
        reason = (f"interrupted by {stopped_by} after step {tally.steps if tally else 0} "
                  f"(t = {tally.t if tally else 0:.6g} s; on the way: {reason})")
    tally = tally or Tally(0.0, EnergyBound(0.0, case.limits.energy_margin))
    units = dict(setup.geometry.integral_units) if setup else {}
    ranges = probe_ranges(case.resolved.get("output", {}).get("probes", []), _written_series(results), units)
    summary = {
        "status": status,
        "reason": reason,
        **({"traceback": crash} if crash else {}),
        "multilayer_version": __version__,
        "case": dict(case.resolved),
        "case_hash": case.digest,
        "plugins": plugin_versions(case, registry),
        **({"units": units} if setup else {}),
        "dofs": setup.dof_counts() if setup else {},
        "steps": tally.steps,
        "t": tally.t,
        "dt": case.time.dt,
        **clock.summary(tally.clock, case),
        "scheme": _scheme(coupler),
        "wall_time_s": tally.wall_time_s + time.perf_counter() - wall_t0,
        "timings": _timings(setup),
        "factorizations": _factorizations(setup),
        "krylov": _krylov(setup),
        **_newton(setup),
        "energy": {"max_relative_residual": tally.max_rel},
        "probe_ranges": ranges,
        **({"volume": tally.volume.summary()} if tally.volume is not None else {}),
        **_iterations(tally.iterations),
        **({"resumed_from": resumed_from} if saved is not None else {}),
        **({"checkpoint": {"every": checkpoint_every, "file": checkpoint.FILE, "arrays": checkpoint.ARRAYS}}
           if checkpoint_every else {}),
    }
    signals.finishing = True
    try:
        read = _readouts(case, setup, results)
        summary.update(read)
        results.write_summary(summary)
    finally:
        results.release()
    return RunResult(status, reason, results.path, tally.steps, tally.max_rel, tally.t, dict(tally.peaks),
                     tally.volume.relative_drift if tally.volume is not None else None, stopped_by, ranges,
                     read.get("cycles"))


def _written_series(results: ResultsFolder | HeldResults) -> dict[str, np.ndarray]:
    """``series.csv`` as written so far (every row of a resumed run too), by column."""
    if results.path is None:
        held = results.tables.get("series.csv")
        return held.arrays() if held is not None else {}
    try:
        return read_series(results.path / "series.csv")
    except (OSError, ResultsError):  # a folder that cannot be read back still gets its summary
        return {}


class Writers:
    """The per-step files: ``series.csv``; with a wall ``eta_lumen.csv`` (η at the lumen's vertices), with a fluid
    ``wss_lumen.csv`` (τ_w at the same vertices); snapshots.

    ``series.csv`` gets its header before the first step, from the columns
    known then (the stored energy's terms, the probes); the first row
    completes it with the step's work and dissipation terms.  The output of
    :func:`~multilayer.runner.stepping.iterate_steps`: :meth:`row`, then :meth:`fields`.
    """

    def __init__(self, results: ResultsFolder | HeldResults, setup: Setup, saved: checkpoint.Checkpoint | None,
                 columns: list[str], signals: Signals):
        self.results, self.setup, self.every = results, setup, setup.case.output.every
        self.signals = signals
        self.keep = saved.tally.steps if saved is not None else None
        if saved is not None:
            results.keep_until(self.keep, saved.snapshots)
        self.series = results.series(columns) if saved is None else None
        self._provisional = saved is None
        #: the lumen tables: (writer, the line vertices it samples, the line vector of a state it writes)
        self.lumen: list[tuple] = []
        if setup.wall is not None:
            self.lumen.append(self._lumen_table("eta_lumen.csv", setup.wall.lines[0], lambda s: setup.eta(s, 0)))
        if setup.gives_wall_shear:
            self.lumen.append(self._lumen_table("wss_lumen.csv", setup.fluid.line, setup.wall_shear))

    def _lumen_table(self, name: str, line, values) -> tuple:
        vertices = line.basis.nodal_dofs[0]
        columns = ["step", "t", *(position_column(z) for z in line.z[vertices])]
        if self.keep is not None and self.results.path is not None:
            columns = _as_written(self.results.path / name, columns)
        return self.results.series(columns, name, self.keep), vertices, values

    def row(self, step: Step) -> None:
        """The step's rows of ``series.csv`` and the lumen tables: all written, or none."""
        row, state = step.row, step.state
        with self.signals.writing():
            if self.series is None or (self._provisional and list(row) != self.series.columns):
                self.series = self.results.series(list(row), keep_until=self.keep)
            self._provisional = False
            self.series.append(row)
            written = [self.series]
            try:
                for table, vertices, values in self.lumen:
                    table.append({"step": state.n, "t": state.t,
                                  **dict(zip(table.columns[2:], values(state)[vertices]))})
                    written.append(table)
            except BaseException:
                for table in written:
                    table.undo()
                raise

    def fields(self, step: Step) -> None:
        """The snapshots, every ``[output] every`` steps; with adaptive steps at every step that landed on an
        output time (``time.output_interval``, ``time.end``)."""
        if not self.every:
            return
        if step.diagnostics.get("landed", 0.0) if self.setup.case.time.adaptive else step.n % self.every == 0:
            with self.signals.writing():
                _snapshot(self.setup, step.state, self.results)


def _as_written(path: Path, columns: list[str]) -> list[str]:
    """The header of the lumen table ``path`` a resumed run appends to, when it names the positions of ``columns``
    unrounded (a table begun before positions were written short: ``z=0.6000000000000001``); else ``columns``."""
    with suppress(OSError, ResultsError, ValueError):
        with open_nofollow(path, os.O_RDONLY, "r") as f:
            header = f.readline().rstrip("\r\n").split(",")
        if len(header) == len(columns) and header[:2] == columns[:2] and all(
                position_column(float(a[2:])) == b for a, b in zip(header[2:], columns[2:])):
            return header
    return columns


def _readouts(case: Case, setup: Setup | None, results: ResultsFolder | HeldResults) -> dict:
    """The summary's ``cycles`` and ``wss`` blocks (:mod:`multilayer.runner.readouts`); an error in them is
    reported in the summary (``readouts_error``, the traceback on stderr), never at the cost of the summary."""
    try:
        return readouts(case, setup, results)
    except Exception as exc:
        print(traceback.format_exc(), file=sys.stderr)
        return {"readouts_error": f"{type(exc).__name__}: {exc}"}


def _iterations(per_step: list[float]) -> dict[str, dict[str, float]]:
    """Sub-iterations per step, for a coupler that reports them (``iterations`` column)."""
    done = [n for n in per_step if not math.isnan(n)]
    if not done:
        return {}
    return {"iterations": {"total": int(sum(done)), "mean": sum(done) / len(done), "max": int(max(done))}}


def _scheme(coupler: Coupler | None) -> dict[str, object]:
    """The ``scheme`` entry of ``summary.json``: the coupler's time scheme, its order and its own parameters."""
    scheme = getattr(coupler, "scheme", None)
    if scheme is None:
        return {}
    return {"name": scheme.name, "order": scheme.order, **({"parameters": scheme.parameters} if scheme.parameters else {})}


def _all_stats(setup: Setup) -> list:
    """The counters of every system of the run: the coupler's (``setup.solvers``) and the fluid's."""
    return [*setup.solvers.values(), *([setup.fluid.stats] if setup.fluid is not None else [])]


def _factorizations(setup: Setup | None) -> dict[str, int]:
    """Factorizations per system: the coupler's own (``wall``, ``monolithic``, ...) and the fluid's."""
    out = {"wall": 0}
    if setup is None:
        return out
    out.update({name: st.factorizations for name, st in setup.solvers.items()})
    if setup.fluid is not None:
        out["fluid"] = setup.fluid.stats.factorizations
    return out


def _krylov(setup: Setup | None) -> dict[str, dict[str, int | float]]:
    """Krylov solves and iterations per system that had any (``[solver] reuse = "krylov"``, or
    ``factors = "single"``), the iterative-refinement sweeps after direct solves and the fallbacks from
    single- to double-precision factors where there were any, and the factorization's price in GMRES
    iterations the system was refactorized at."""
    if setup is None:
        return {}
    stats = dict(setup.solvers)
    if setup.fluid is not None:
        stats["fluid"] = setup.fluid.stats
    out = {}
    for name, st in stats.items():
        row = {"solves": st.krylov_solves, "iterations": st.krylov_iterations}
        if getattr(st, "refinements", 0):
            row["refinements"] = st.refinements
        if getattr(st, "fallbacks", 0):
            row["fallbacks"] = st.fallbacks
        if any(row.values()):
            if getattr(st, "factorization_cost", None) is not None:  # what the reuse rule refactorized at
                row["factorization_cost"] = round(st.factorization_cost, 3)
            out[name] = row
    return out


def _newton(setup: Setup | None) -> dict[str, dict[str, dict[str, int | float]]]:
    """The Newton solves of a nonlinear wall per system that had any (``newton``; a linear wall has none): how
    many, their corrections in all, the most one took, the largest relative residual one ended at and the
    last one's (:mod:`multilayer.numerics.newton`)."""
    if setup is None:
        return {}
    out = {name: {"solves": st.newton_solves, "iterations": st.newton_iterations,
                  "max_iterations": st.newton_max_iterations, "max_residual": st.newton_residual,
                  "last_residual": st.newton_last_residual}
           for name, st in setup.solvers.items() if st.newton_solves}
    return {"newton": out} if out else {}


def _timings(setup: Setup | None) -> dict[str, float]:
    """Seconds per phase, all systems together (every key present, 0 when the run never started)."""
    out = dict.fromkeys(("assembly", "factorization", "solves", "output", "ledger"), 0.0)
    if setup is None:
        return out
    stats = _all_stats(setup)
    out["assembly"] = setup.timings.get("assembly", 0.0)
    out["output"] = setup.timings.get("output", 0.0)
    out["factorization"] = sum(st.factorization_s for st in stats)
    out["solves"] = sum(st.solve_s for st in stats)
    if setup.fluid is not None:
        out["assembly"] += setup.fluid.timings.get("assembly", 0.0)
        out["ledger"] += setup.fluid.timings.get("ledger", 0.0)
    return out
