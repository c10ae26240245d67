"""Seconds per coupled step, per coupler and per phase, measured side by side; printed as JSON.

Not a test: nothing is asserted.  Every coupler runs the same case (by
default the quick-start pulse, ``cases/pulse-koiter-thick.toml``) and the
couplers take their steps **in turn** (step 1 of each, then step 2 of each,
...), so the load of a shared machine falls on all of them alike.  For each
coupler it prints the median over the steps (the first, a warm-up, left out)
of the wall time of a step and of its phases: assembly, factorization and
solves of every system (fluid, wall, monolithic), and the ledger; the DOF
counts; the Krylov iterations per step; the ratio of the step to
kinematic-splitting's and to one fresh factorization of the fluid system.
That factorization is timed in the same loop, once per round of steps (the
first run's latest fluid matrix, free DOFs, factorized by that run's
backend on the ordering it keeps and in its precision — and, for
comparison, by SuperLU with COLAMD, ``superlu-colamd``, and in double
precision when the first run's factors are single), so the ratio compares times taken side by side
whether or not the runs themselves refactorize.  ``--vary KEY=A,B`` runs
every coupler once per value (e.g. ``solver.reuse=krylov,none``).

    python benchmarks/coupled_step.py                       # every coupler, 60 × 8 cells, 30 steps
    python benchmarks/coupled_step.py --set mesh.nz=240 --set mesh.nr=32 --steps 10
    python benchmarks/coupled_step.py --couplers '{model="monolithic",scheme="crank-nicolson"}'
    python benchmarks/coupled_step.py --couplers '"kinematic-splitting"' --vary solver.reuse=krylov,none
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

from multilayer.case.casefile import load_case
from multilayer.case.keys import split_values
from multilayer.coupling.build import prepare
from multilayer.numerics.linsolve import SolverStats, factorize
from multilayer.numerics.threads import blas_threads
from multilayer.plugin.registry import Registry
from multilayer.scene.setup import Setup

CASE = Path(__file__).parents[1] / "cases" / "pulse-koiter-thick.toml"
COUPLERS = ('"kinematic-splitting"', '{model="kinematic-splitting",beta=1}',
            '{model="kinematic-splitting",scheme="crank-nicolson",beta=1}', '{model="monolithic"}',
            '{model="monolithic",scheme="crank-nicolson"}', '{model="monolithic",scheme="bdf2"}',
            '{model="dirichlet-neumann-implicit"}')


def counters(setup: Setup) -> dict[str, float]:
    """Every phase counter of the setup, the fluid's and the coupler's systems (seconds so far)."""
    out = {"assembly": setup.timings["assembly"]}
    for name, st in setup.solvers.items():
        out[f"factorization.{name}"] = st.factorization_s
        out[f"solves.{name}"] = st.solve_s
    if setup.fluid is not None:
        out["assembly"] += setup.fluid.timings["assembly"]
        out["ledger"] = setup.fluid.timings["ledger"]
        out["factorization.fluid"] = setup.fluid.stats.factorization_s
        out["solves.fluid"] = setup.fluid.stats.solve_s
    stats = [*setup.solvers.values(), *([setup.fluid.stats] if setup.fluid is not None else [])]
    out["krylov_iterations"] = float(sum(st.krylov_iterations for st in stats))
    out["factorizations"] = float(sum(st.factorizations for st in stats))
    return out


def fresh_factorizations_s(setup: Setup, colamd: bool = True) -> dict[str, float]:
    """Seconds of fresh factorizations of the fluid's latest matrix ({} before there is one).

    ``fresh``: by the run's own backend instance, on the ordering it keeps for
    the pattern and in the run's precision (``[solver] factors``: what a
    refactorizing step pays); ``double``, when the run's factors are single:
    the same in double precision, what a direct solve needs; ``colamd``
    (unless not asked for): SuperLU with its COLAMD ordering
    (``superlu-colamd``, what every step paid before).
    ``benchmarks/scaling.py`` times the same.
    """
    A = getattr(setup.fluid.discrete, "last_matrix", None) if setup.fluid is not None else None
    if A is None:
        return {}
    single = setup.case.reuse.factors == "single"
    out = {}
    for name, stats, backend, precision in (
            ("fresh", SolverStats(backends=setup.fluid.stats.backends), setup.case.solver, single),
            *([("double", SolverStats(backends=setup.fluid.stats.backends), setup.case.solver, False)]
              if single else []),
            *([("colamd", SolverStats(), "superlu-colamd", False)] if colamd else [])):
        t0 = time.perf_counter()
        factorize(A, stats, backend, single=precision)
        out[name] = time.perf_counter() - t0
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", type=Path, default=CASE)
    ap.add_argument("--couplers", default=",".join(COUPLERS), help="comma list of [coupler] values")
    ap.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--steps", type=int, default=30, help="steps per coupler (the first is a warm-up)")
    ap.add_argument("--vary", action="append", default=[], metavar="KEY=A,B",
                    help="run every coupler once per value of KEY (repeatable: the product)")
    args = ap.parse_args(argv)
    registry = Registry.load()
    variants = [[]]
    for vary in args.vary:
        key, _, values = vary.partition("=")
        variants = [[*v, f"{key}={value}"] for v in variants for value in split_values(values)]
    runs = {}
    for spec in split_values(args.couplers):
        for sets in variants:
            case = load_case(args.case, [*args.sets, *sets, f"coupler={spec}"], registry)
            setup, coupler = prepare(case, registry)
            state = coupler.initial_state(setup)
            label = " ".join([spec, *sets])
            runs[label] = {"setup": setup, "steps": coupler.evolve(setup, state), "samples": [],
                           "coupler": spec, "sets": sets}
    fresh = []
    reference = next(iter(runs.values()))["setup"]
    for _ in range(args.steps):
        for run in runs.values():
            before = counters(run["setup"])
            with blas_threads(run["setup"].case.threads):  # each run's [solver] threads, outside the timing
                t0 = time.perf_counter()
                next(run["steps"])
                wall = time.perf_counter() - t0
            after = counters(run["setup"])
            run["samples"].append({"step": wall, **{k: after[k] - before.get(k, 0.0) for k in after}})
        with blas_threads(reference.case.threads):
            fresh.append(fresh_factorizations_s(reference))
    fresh = [f for f in fresh[1:] if f]
    fresh_s = {k: statistics.median(f[k] for f in fresh) for k in fresh[0]} if fresh else {}
    rows = {}
    for label, run in runs.items():
        warm = run["samples"][1:] or run["samples"]
        keys = sorted({k for s in warm for k in s})
        row = {"coupler": run["coupler"], "sets": run["sets"], "dofs": run["setup"].dof_counts(),
               "steps": len(warm)}
        row.update({f"median.{k}": statistics.median(s.get(k, 0.0) for s in warm) for k in keys})
        # the mean counts the steps that refactorize, which the median leaves out: what a run pays per step
        row["mean.step"] = statistics.fmean(s["step"] for s in warm)
        row["mean.krylov_iterations"] = statistics.fmean(s.get("krylov_iterations", 0.0) for s in warm)
        row["mean.factorizations"] = statistics.fmean(s.get("factorizations", 0.0) for s in warm)
        rows[label] = row
    baseline = next(iter(rows.values()))
    for row in rows.values():
        row["ratio_to_first_run"] = row["median.step"] / baseline["median.step"]
        if fresh_s:
            row["median.fresh_fluid_factorization"] = fresh_s["fresh"]
            row["ratio_to_one_fluid_factorization"] = row["median.step"] / fresh_s["fresh"]
            row["median.colamd_fluid_factorization"] = fresh_s["colamd"]
            row["ratio_to_one_colamd_factorization"] = row["median.step"] / fresh_s["colamd"]
            row["mean_ratio_to_one_fluid_factorization"] = row["mean.step"] / fresh_s["fresh"]
            if "double" in fresh_s:  # the reference run's factors are single: also against a double one
                row["median.double_fluid_factorization"] = fresh_s["double"]
                row["ratio_to_one_double_fluid_factorization"] = row["median.step"] / fresh_s["double"]
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
