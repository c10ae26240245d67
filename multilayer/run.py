"""Running a case: build the scene, let the coupler advance it, write everything.

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
from multilayer.registry import Registry
from multilayer.results import ResultsFolder
from multilayer.scene import Scene


class RunFailed(Exception):
    """The run cannot go on; the message says where and when."""


@attrs.frozen
class RunResult:
    status: str
    reason: str = ""
    out: Path | None = None
    steps: int = 0
    max_relative_residual: float = 0.0


def check_state(scene: Scene, t: float, row: dict[str, float]) -> None:
    """Stop on a non-finite value or a wall collapsing onto the axis (R + η ≤ 0)."""
    bad = [k for k, v in row.items() if not math.isfinite(v)]
    if bad:
        raise RunFailed(f"non-finite value at t = {t:.6g} s in {', '.join(sorted(bad)[:5])}")
    if scene.wall_state is not None:
        for name, vec in (("wall displacement", scene.wall_state.d), ("wall velocity", scene.wall_state.V)):
            if not np.all(np.isfinite(vec)):
                raise RunFailed(f"non-finite {name} at t = {t:.6g} s")
        eta = scene.eta(0)
        gap = scene.case.geometry.radius + eta
        if np.min(gap) <= 0.0:
            i = int(np.argmin(gap))
            z = scene.wall.lines[0].z[i]
            raise RunFailed(f"wall collapse at t = {t:.6g} s, z = {z:.6g} cm: R + η = {gap[i]:.6g} cm ≤ 0")


def _snapshot(scene: Scene, results: ResultsFolder, t: float, step: int) -> None:
    if scene.wall is not None:
        pts, cells, data = scene.wall_snapshot()
        results.snapshot("wall", pts, cells, data, t, step)
    if scene.fluid_state is not None:
        pts, cells, data = scene.fluid_snapshot()
        results.snapshot("fluid", pts, cells, data, t, step)


def run_case(case: Case, out: str | Path, registry: Registry | None = None) -> RunResult:
    """Run ``case`` and write its results folder ``out``.

    Returns the :class:`RunResult`; the same status is in ``summary.json``.
    """
    wall_t0 = time.perf_counter()
    registry = registry or Registry.load()
    results = ResultsFolder(Path(out))
    status, reason, steps, max_rel, crash = "ok", "", 0, 0.0, ""
    scene: Scene | None = None
    try:
        try:
            scene = Scene.build(case, registry)
        except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:
            raise RunFailed(f"setting up the scene failed: {exc}") from exc
        scene.coupler.prepare(scene)
        probes = scene.probe_rows(case.output.probes)
        every = case.output.every
        series = None
        t_out = time.perf_counter()
        if every:
            _snapshot(scene, results, 0.0, 0)
        scene.timings["output"] += time.perf_counter() - t_out
        for report in scene.coupler.evolve(scene):
            check_state(scene, report.t, dict(report.ledger))
            t_out = time.perf_counter()
            row = {"step": report.step, "t": report.t, **report.ledger, **scene.probe_values(probes)}
            if series is None:
                series = results.series(list(row))
            series.append(row)
            steps = report.step
            max_rel = max(max_rel, float(report.ledger.get("energy.relative_residual", 0.0)))
            if every and report.step % every == 0:
                _snapshot(scene, results, report.t, report.step)
            scene.timings["output"] += time.perf_counter() - t_out
    except RunFailed as exc:
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
        "dofs": scene.dof_counts() if scene else {},
        "steps": steps,
        "dt": case.time.dt,
        "wall_time_s": time.perf_counter() - wall_t0,
        "timings": _timings(scene),
        "factorizations": _factorizations(scene),
        "energy": {"max_relative_residual": max_rel},
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


def _fluid_step(scene: Scene | None):
    return scene.fluid.discrete if scene is not None and scene.fluid_state is not None else None


def _factorizations(scene: Scene | None) -> dict[str, int]:
    out = {"wall": scene.stats.factorizations if scene else 0}
    if _fluid_step(scene) is not None:
        out["fluid"] = _fluid_step(scene).stats.factorizations
    return out


def _timings(scene: Scene | None) -> dict[str, float]:
    """Seconds per phase, wall and fluid together (every key present, 0 when the scene never started)."""
    if scene is None:
        return dict.fromkeys(("assembly", "factorization", "solves", "output", "ledger"), 0.0)
    out = {
        "assembly": scene.timings.get("assembly", 0.0),
        "factorization": scene.stats.factorization_s,
        "solves": scene.stats.solve_s,
        "output": scene.timings.get("output", 0.0),
        "ledger": 0.0,
    }
    fluid = _fluid_step(scene)
    if fluid is not None:
        out["assembly"] += fluid.assembly_s
        out["factorization"] += fluid.stats.factorization_s
        out["solves"] += fluid.stats.solve_s
        out["ledger"] += fluid.ledger_s
    return out
