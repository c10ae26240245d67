"""Running a case: build the setup, let the coupler advance the state, close the ledger, write everything.

The results folder is a contract other tools rely on:

* ``summary.json`` — status (``ok`` / ``failed`` with a ``reason``), the
  resolved case and its hash, plugin versions, DOF counts, steps, wall time,
  per-phase timings and the energy ledger's largest relative residual;
* ``series.csv`` — one row per step: ``t``, every ledger term, every probe;
* ``<part>_NNNNNN.vtu`` + ``<part>.pvd`` — field snapshots for ParaView.

A run that fails (a non-finite value, a collapsing wall) stops cleanly and
keeps every row and snapshot written so far.
"""

from __future__ import annotations

import math
import sys
import time
import traceback
from pathlib import Path

import attrs
import numpy as np

from multilayer import __version__
from multilayer.case import Case
from multilayer.interfaces import SchemeFailure
from multilayer.registry import Registry
from multilayer.results import ResultsFolder
from multilayer import ledger
from multilayer.setup import Setup
from multilayer.state import State


class RunFailed(Exception):
    """The run cannot go on; the message says where and when."""


@attrs.frozen
class RunResult:
    status: str
    reason: str = ""
    out: Path | None = None
    steps: int = 0
    max_relative_residual: float = 0.0


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


def run_case(case: Case, out: str | Path, registry: Registry | None = None) -> RunResult:
    """Run ``case`` and write its results folder ``out``.

    The coupler advances states; this loop closes the energy ledger of each
    step from the terms the coupler reports (SCHEME §4), evaluates the
    probes and writes rows and snapshots.  Returns the :class:`RunResult`;
    the same status is in ``summary.json``.
    """
    wall_t0 = time.perf_counter()
    registry = registry or Registry.load()
    results = ResultsFolder(Path(out))
    status, reason, steps, max_rel, crash = "ok", "", 0, 0.0, ""
    iterations: list[float] = []
    setup: Setup | None = None
    try:
        try:
            setup = Setup.build(case, registry)
            state = setup.coupler.initial_state(setup)
        except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:
            raise RunFailed(f"setting up the scene failed: {exc}") from exc
        previous = sum(setup.coupler.energy(setup, state).values())
        bound = EnergyBound(previous, case.limits.energy_margin)
        probes = setup.probe_rows(case.output.probes)
        every = case.output.every
        series = None
        t_out = time.perf_counter()
        if every:
            _snapshot(setup, state, results)
        setup.timings["output"] += time.perf_counter() - t_out
        for state, report in setup.coupler.evolve(setup, state):
            terms = ledger.close(report.stored, previous, report.work, report.dissipation)
            previous = terms["energy.total"]
            check_state(setup, state, {**terms, **report.diagnostics})
            iterations.append(report.diagnostics.get("iterations", math.nan))
            t_out = time.perf_counter()
            row = {"step": state.n, "t": state.t, **terms, **report.diagnostics,
                   **setup.probe_values(probes, state)}
            if series is None:
                series = results.series(list(row))
            series.append(row)
            steps = state.n
            max_rel = max(max_rel, terms["energy.relative_residual"])
            if every and state.n % every == 0:
                _snapshot(setup, state, results)
            setup.timings["output"] += time.perf_counter() - t_out
            bound.check(state.t, terms)  # after the row is written: the row that breaks the bound is kept
    except (RunFailed, SchemeFailure) as exc:
        status, reason = "failed", str(exc)
    except (FloatingPointError, np.linalg.LinAlgError, RuntimeError, ValueError) as exc:
        status, reason = "failed", f"{type(exc).__name__} after step {steps}: {exc}"
    except Exception as exc:  # a bug: still keep the results and say where
        status, reason = "failed", f"{type(exc).__name__} after step {steps}: {exc}"
        crash = traceback.format_exc()
        print(crash, file=sys.stderr)
    summary = {
        "status": status,
        "reason": reason,
        **({"traceback": crash} if crash else {}),
        "multilayer_version": __version__,
        "case": dict(case.resolved),
        "case_hash": case.digest,
        "plugins": _plugin_versions(case, registry),
        "dofs": setup.dof_counts() if setup else {},
        "steps": steps,
        "dt": case.time.dt,
        "scheme": _scheme(setup),
        "wall_time_s": time.perf_counter() - wall_t0,
        "timings": _timings(setup),
        "factorizations": _factorizations(setup),
        "energy": {"max_relative_residual": max_rel},
        **_iterations(iterations),
    }
    results.write_summary(summary)
    return RunResult(status, reason, Path(out), steps, max_rel)


def _plugin_versions(case: Case, registry: Registry) -> dict[str, dict[str, str]]:
    specs = [("coupler", case.coupler), *(("layer", s) for s in case.layers)]
    if case.fluid is not None:
        specs.append(("fluid", case.fluid))
    out = {}
    for kind, spec in specs:
        reg = registry.find(kind, spec.model)
        if reg is not None:
            out[spec.path] = {"name": spec.model, "package": reg.package, "version": reg.version}
    return out


def _iterations(per_step: list[float]) -> dict[str, dict[str, float]]:
    """Sub-iterations per step, for a coupler that reports them (``iterations`` column)."""
    done = [n for n in per_step if not math.isnan(n)]
    if not done:
        return {}
    return {"iterations": {"total": int(sum(done)), "mean": sum(done) / len(done), "max": int(max(done))}}


def _scheme(setup: Setup | None) -> dict[str, object]:
    scheme = getattr(setup.coupler, "scheme", None) if setup is not None else None
    return {"name": scheme.name, "order": scheme.order} if scheme is not None else {}


def _factorizations(setup: Setup | None) -> dict[str, int]:
    """Factorizations per system: the coupler's own (``wall``, ``monolithic``, ...) and the fluid's."""
    out = {"wall": 0}
    if setup is None:
        return out
    out.update({name: st.factorizations for name, st in setup.solvers.items()})
    if setup.fluid is not None:
        out["fluid"] = setup.fluid.stats.factorizations
    return out


def _timings(setup: Setup | None) -> dict[str, float]:
    """Seconds per phase, all systems together (every key present, 0 when the run never started)."""
    out = dict.fromkeys(("assembly", "factorization", "solves", "output", "ledger"), 0.0)
    if setup is None:
        return out
    stats = [*setup.solvers.values(), *([setup.fluid.stats] if setup.fluid is not None else [])]
    out["assembly"] = setup.timings.get("assembly", 0.0)
    out["output"] = setup.timings.get("output", 0.0)
    out["factorization"] = sum(st.factorization_s for st in stats)
    out["solves"] = sum(st.solve_s for st in stats)
    if setup.fluid is not None:
        out["assembly"] += setup.fluid.timings.get("assembly", 0.0)
        out["ledger"] += setup.fluid.timings.get("ledger", 0.0)
    return out
