"""Running a case: build the setup, let the coupler advance the state, close the ledger, write everything.

The results folder is a contract other tools rely on:

* ``summary.json`` — status (``ok``, ``failed`` with a ``reason``, or
  ``interrupted``), the resolved case and its hash, plugin versions, DOF
  counts, steps, wall time, per-phase timings, the energy ledger's largest
  relative residual, sub-iterations when the coupler reports them;
* ``series.csv`` — one row per step: ``t``, every ledger term, every probe;
* ``eta_lumen.csv`` — η on the lumen line at every vertex, every step (when there is a wall);
* ``<part>_NNNNNN.vtu`` + ``<part>.pvd`` — field snapshots for ParaView;
* ``checkpoint.pkl`` — the whole state every ``checkpoint_every`` steps, for :func:`resume_run`.

A run that fails (a non-finite value, a collapsing wall, energy beyond
the work put in) or is interrupted (SIGINT, SIGTERM) stops cleanly and keeps
every row and snapshot written so far.
"""

from __future__ import annotations

import math
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import attrs
import numpy as np

from multilayer.case.model import Case
from multilayer.coupling.build import prepare
from multilayer.coupling.contract import Coupler, SchemeFailure
from multilayer.numerics.threads import blas_threads
from multilayer.plugin.registry import Registry, plugin_versions
from multilayer.results.folder import ResultsFolder
from multilayer.run import checkpoint, ledger
from multilayer.scene.setup import Setup
from multilayer.scene.state import State
from multilayer.version import __version__


class RunFailed(Exception):
    """The run cannot go on; the message says where and when."""


def check_state(setup: Setup, state: State, row: dict[str, float]) -> None:
    """Stop on a non-finite value, a wall collapsing onto the axis (R + η ≤ 0) or one blown outward.

    Outward means |η| on the lumen beyond ``[solver] max_displacement`` × R.
    """
    t = state.t
    bad = [k for k, v in row.items() if not math.isfinite(v)]
    if bad:
        raise RunFailed(f"non-finite value at t = {t:.6g} s in {', '.join(sorted(bad)[:5])}")
    if state.wall is not None:
        for name, vec in (("wall displacement", state.wall.d), ("wall velocity", state.wall.V)):
            if not np.all(np.isfinite(vec)):
                raise RunFailed(f"non-finite {name} at t = {t:.6g} s")
        gap = setup.case.geometry.radius + setup.eta(state, 0)
        if np.min(gap) <= 0.0:
            i = int(np.argmin(gap))
            z = setup.wall.lines[0].z[i]
            raise RunFailed(f"wall collapse at t = {t:.6g} s, z = {z:.6g} cm: R + η = {gap[i]:.6g} cm ≤ 0")
        limit = setup.case.limits.max_displacement * setup.case.geometry.radius
        eta = gap - setup.case.geometry.radius
        i = int(np.argmax(np.abs(eta)))
        if abs(eta[i]) > limit:
            how = "blow-out (outward)" if eta[i] > 0 else "collapse (inward)"
            raise RunFailed(f"wall {how} at t = {t:.6g} s, z = {setup.wall.lines[0].z[i]:.6g} cm: "
                            f"|η| = {abs(eta[i]):.6g} cm > {setup.case.limits.max_displacement:g} R "
                            f"([solver] max_displacement)")


class EnergyBound:
    """Energy may never exceed the initial energy plus the work put in (a stable scheme's bound).

    Checked after every step with the margin ``[solver] energy_margin``: beyond
    it the scheme is unstable and the run stops, naming time and amounts.
    """

    def __init__(self, initial: float, margin: float):
        self.initial, self.margin, self.work, self.scale = initial, margin, 0.0, abs(initial)

    def check(self, t: float, terms: dict[str, float]) -> None:
        self.work += sum(v for k, v in terms.items() if k.startswith("work."))
        bound = self.initial + self.work
        self.scale = max(self.scale, abs(self.initial) + abs(self.work), abs(terms["energy.total"]))
        excess = terms["energy.total"] - bound
        if excess > self.margin * self.scale:
            raise RunFailed(f"energy grew beyond the work put in at t = {t:.6g} s: E = {terms['energy.total']:.6g} "
                            f"> E⁰ + work = {bound:.6g} (by {excess / self.scale:.3g} of the energy scale; "
                            f"[solver] energy_margin = {self.margin:g}): the scheme is unstable here")


def _snapshot(setup: Setup, state: State, results: ResultsFolder) -> None:
    if setup.wall is not None:
        pts, cells, data = setup.wall_snapshot(state)
        results.snapshot("wall", pts, cells, data, state.t, state.n)
    if setup.fluid is not None:
        pts, cells, data = setup.fluid_snapshot(state)
        results.snapshot("fluid", pts, cells, data, state.t, state.n)


@attrs.frozen
class RunResult:
    status: str
    reason: str = ""
    out: Path | None = None
    steps: int = 0
    max_relative_residual: float = 0.0
    t: float = 0.0
    peaks: dict = attrs.field(factory=dict)  #: max |value| of every η probe


@attrs.define
class Tally:
    """What the loop carries from step to step besides the state: the ledger and the counts.

    It is part of a checkpoint, so a resumed run goes on with the same numbers.
    """

    previous: float  #: the stored energy before the next step
    bound: EnergyBound
    steps: int = 0
    t: float = 0.0
    max_rel: float = 0.0
    iterations: list[float] = attrs.field(factory=list)
    peaks: dict[str, float] = attrs.field(factory=dict)
    wall_time_s: float = 0.0  #: wall time of earlier sessions of a resumed run


class Interrupted(Exception):
    """SIGINT or SIGTERM: the run stops after the current step."""


@contextmanager
def interruptible() -> Iterator[Callable[[], str | None]]:
    """Catch SIGINT and SIGTERM while a run goes on; yields a function naming the signal caught (or None).

    A first signal lets the current step finish; a second SIGINT abandons it.
    Handlers are installed only in the main thread (elsewhere nothing changes).
    """
    caught: list[str] = []
    if threading.current_thread() is not threading.main_thread():
        yield lambda: None
        return

    def handler(signum, frame):
        name = signal.Signals(signum).name
        if caught and signum == signal.SIGINT:
            raise Interrupted(name)
        caught.append(name)

    old = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield lambda: caught[0] if caught else None
    finally:
        for sig, h in old.items():
            signal.signal(sig, h)


def run_case(case: Case, out: str | Path, registry: Registry | None = None, *, checkpoint_every: int = 0,
             progress: Callable[[Tally, dict], None] | None = None) -> RunResult:
    """Run ``case`` and write its results folder ``out``.

    The coupler advances states; this loop closes the energy ledger of each
    step from the terms the coupler reports ([theory](docs/theory.md) §7),
    evaluates the probes and writes rows and snapshots; with
    ``checkpoint_every`` > 0 it writes ``checkpoint.pkl`` every so many steps
    and when interrupted.  ``progress(tally, row)`` is called after every
    step.  Returns the :class:`RunResult`; the same status is in ``summary.json``.
    """
    registry = registry or Registry.load()
    results = ResultsFolder(Path(out))
    with blas_threads(case.threads):
        return _run(case, results, registry, None, checkpoint_every, progress)


def resume_run(out: str | Path, until: float | None = None, registry: Registry | None = None, *,
               checkpoint_every: int | None = None,
               progress: Callable[[Tally, dict], None] | None = None) -> RunResult:
    """Continue the run of the results folder ``out`` from its ``checkpoint.pkl`` (to ``until`` s if given).

    Rows and snapshots written after the checkpoint are dropped first, so a
    run resumed from step n writes the same files as one never stopped.
    Raises :class:`checkpoint.CheckpointError` when there is no usable
    checkpoint, or the plugins or the case differ from the checkpoint's.
    """
    registry = registry or Registry.load()
    saved = checkpoint.load(Path(out), registry, until)
    results = ResultsFolder(Path(out), fresh=False)
    every = saved.checkpoint_every if checkpoint_every is None else checkpoint_every
    with blas_threads(getattr(saved.case, "threads", 1)):
        return _run(saved.case, results, registry, saved, every, progress)


def _run(case: Case, results: ResultsFolder, registry: Registry, saved: checkpoint.Checkpoint | None,
         checkpoint_every: int, progress) -> RunResult:
    wall_t0 = time.perf_counter()
    status, reason, crash = "ok", "", ""
    setup: Setup | None = None
    coupler: Coupler | None = None
    tally: Tally | None = saved.tally if saved is not None else None
    resumed_from = saved.tally.steps if saved is not None else None
    try:
        with interruptible() as interrupted:
            try:
                setup, coupler = prepare(case, registry)
                state = saved.state if saved is not None else coupler.initial_state(setup)
            except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:
                raise RunFailed(f"setting up the scene failed: {exc}") from exc
            if tally is None:
                energy = sum(coupler.energy(setup, state).values())
                tally = Tally(energy, EnergyBound(energy, case.limits.energy_margin))
            probes = setup.probe_rows(case.output.probes)
            eta_probes = [p.name for p in case.output.probes if p.quantity == "eta"]
            every = case.output.every
            writers = Writers(results, setup, saved, ["step", "t", *coupler.energy(setup, state),
                                                      "energy.total", "energy.residual", "energy.relative_residual",
                                                      *probes])
            t_out = time.perf_counter()
            if every and saved is None:
                _snapshot(setup, state, results)
            setup.timings["output"] += time.perf_counter() - t_out
            for state, report in coupler.evolve(setup, state):
                terms = ledger.close(report.stored, tally.previous, report.work, report.dissipation)
                tally.previous = terms["energy.total"]
                check_state(setup, state, {**terms, **report.diagnostics})
                tally.iterations.append(report.diagnostics.get("iterations", math.nan))
                t_out = time.perf_counter()
                row = {"step": state.n, "t": state.t, **terms, **report.diagnostics,
                       **setup.probe_values(probes, state)}
                writers.write(row, state)
                tally.steps, tally.t = state.n, state.t
                tally.max_rel = max(tally.max_rel, terms["energy.relative_residual"])
                for name in eta_probes:
                    tally.peaks[name] = max(tally.peaks.get(name, 0.0), abs(row[name]))
                if every and state.n % every == 0:
                    _snapshot(setup, state, results)
                setup.timings["output"] += time.perf_counter() - t_out
                tally.bound.check(state.t, terms)  # after the row is written: the row that breaks it is kept
                if progress is not None:
                    progress(tally, row)
                if checkpoint_every and (state.n % checkpoint_every == 0 or interrupted()):
                    checkpoint.save(results.path, case, registry, state, tally, results.snapshots, checkpoint_every,
                                    time.perf_counter() - wall_t0)
                    for stats in _all_stats(setup):  # a resumed run has no factors: neither may this one
                        stats.refactorize = True
                if interrupted():
                    raise Interrupted(interrupted())
    except Interrupted as exc:
        status = "interrupted"
        reason = f"interrupted by {exc} after step {tally.steps if tally else 0} (t = {tally.t if tally else 0:.6g} s)"
    except (RunFailed, SchemeFailure) as exc:
        status, reason = "failed", str(exc)
    except (FloatingPointError, np.linalg.LinAlgError, RuntimeError, ValueError) as exc:
        status, reason = "failed", f"{type(exc).__name__} after step {tally.steps if tally else 0}: {exc}"
    except Exception as exc:  # a bug: still keep the results and say where
        status, reason = "failed", f"{type(exc).__name__} after step {tally.steps if tally else 0}: {exc}"
        crash = traceback.format_exc()
        print(crash, file=sys.stderr)
    tally = tally or Tally(0.0, EnergyBound(0.0, case.limits.energy_margin))
    summary = {
        "status": status,
        "reason": reason,
        **({"traceback": crash} if crash else {}),
        "multilayer_version": __version__,
        "case": dict(case.resolved),
        "case_hash": case.digest,
        "plugins": plugin_versions(case, registry),
        "dofs": setup.dof_counts() if setup else {},
        "steps": tally.steps,
        "t": tally.t,
        "dt": case.time.dt,
        "scheme": _scheme(coupler),
        "wall_time_s": tally.wall_time_s + time.perf_counter() - wall_t0,
        "timings": _timings(setup),
        "factorizations": _factorizations(setup),
        "krylov": _krylov(setup),
        "energy": {"max_relative_residual": tally.max_rel},
        **_iterations(tally.iterations),
        **({"resumed_from": resumed_from} if saved is not None else {}),
        **({"checkpoint": {"every": checkpoint_every, "file": "checkpoint.pkl"}} if checkpoint_every else {}),
    }
    results.write_summary(summary)
    results.release()
    return RunResult(status, reason, results.path, tally.steps, tally.max_rel, tally.t, dict(tally.peaks))


class Writers:
    """The per-step files: ``series.csv`` and, with a wall, ``eta_lumen.csv`` (η at the lumen's vertices).

    ``series.csv`` gets its header before the first step, from the columns
    known then (the stored energy's terms, the probes); the first row
    completes it with the step's work and dissipation terms.
    """

    def __init__(self, results: ResultsFolder, setup: Setup, saved: checkpoint.Checkpoint | None,
                 columns: list[str]):
        self.results, self.setup = results, setup
        self.keep = saved.tally.steps if saved is not None else None
        if saved is not None:
            results.keep_until(self.keep, saved.snapshots)
        self.series = results.series(columns) if saved is None else None
        self._provisional = saved is None
        self.eta = None
        if setup.wall is not None:
            line = setup.wall.lines[0]
            self._vertices = line.basis.nodal_dofs[0]
            z = line.z[self._vertices]
            self.eta = results.series(["step", "t", *(f"z={v!r}" for v in map(float, z))], "eta_lumen.csv",
                                      self.keep)

    def write(self, row: dict, state: State) -> None:
        if self.series is None or (self._provisional and list(row) != self.series.columns):
            self.series = self.results.series(list(row), keep_until=self.keep)
        self._provisional = False
        self.series.append(row)
        if self.eta is not None:
            eta = self.setup.eta(state, 0)[self._vertices]
            self.eta.append({"step": state.n, "t": state.t, **dict(zip(self.eta.columns[2:], eta))})


def _iterations(per_step: list[float]) -> dict[str, dict[str, float]]:
    """Sub-iterations per step, for a coupler that reports them (``iterations`` column)."""
    done = [n for n in per_step if not math.isnan(n)]
    if not done:
        return {}
    return {"iterations": {"total": int(sum(done)), "mean": sum(done) / len(done), "max": int(max(done))}}


def _scheme(coupler: Coupler | None) -> dict[str, object]:
    scheme = getattr(coupler, "scheme", None)
    return {"name": scheme.name, "order": scheme.order} if scheme is not None else {}


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
