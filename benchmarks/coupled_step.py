"""Seconds per coupled step, per coupler and per phase, measured side by side; printed as JSON.

Not a test: nothing is asserted.  Every coupler runs the same case (by
default the quick-start pulse, ``cases/pulse-koiter-thick.toml``) and the
couplers take their steps **in turn** (step 1 of each, then step 2 of each,
...), so the load of a shared machine falls on all of them alike.  For each
coupler it prints the median over the steps (the first, a warm-up, left out)
of the wall time of a step and of its phases: assembly, factorization and
solves of every system (fluid, wall, monolithic), and the ledger; the DOF
counts; the ratio of the step to kinematic-splitting's and to one fresh
factorization of the fluid system (the fluid's own median factorization).

    python benchmarks/coupled_step.py                       # every coupler, 60 × 8 cells, 30 steps
    python benchmarks/coupled_step.py --set mesh.nz=240 --set mesh.nr=32 --steps 10
    python benchmarks/coupled_step.py --couplers '{model="monolithic",scheme="crank-nicolson"}'
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

from multilayer.casefile import load_case
from multilayer.registry import Registry
from multilayer.setup import Setup
from multilayer.variants import split_values

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
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", type=Path, default=CASE)
    ap.add_argument("--couplers", default=",".join(COUPLERS), help="comma list of [coupler] values")
    ap.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--steps", type=int, default=30, help="steps per coupler (the first is a warm-up)")
    args = ap.parse_args(argv)
    registry = Registry.load()
    runs = {}
    for coupler in split_values(args.couplers):
        case = load_case(args.case, [*args.sets, f"coupler={coupler}"], registry)
        setup = Setup.build(case, registry)
        state = setup.coupler.initial_state(setup)
        runs[coupler] = {"setup": setup, "steps": setup.coupler.evolve(setup, state), "samples": []}
    for _ in range(args.steps):
        for run in runs.values():
            before = counters(run["setup"])
            t0 = time.perf_counter()
            next(run["steps"])
            wall = time.perf_counter() - t0
            after = counters(run["setup"])
            run["samples"].append({"step": wall, **{k: after[k] - before.get(k, 0.0) for k in after}})
    rows = {}
    for coupler, run in runs.items():
        warm = run["samples"][1:] or run["samples"]
        keys = sorted({k for s in warm for k in s})
        row = {"coupler": coupler, "dofs": run["setup"].dof_counts(), "steps": len(warm)}
        row.update({f"median.{k}": statistics.median(s.get(k, 0.0) for s in warm) for k in keys})
        rows[coupler] = row
    baseline = rows.get(COUPLERS[0], next(iter(rows.values())))
    fresh = baseline.get("median.factorization.fluid") or None
    for row in rows.values():
        row["ratio_to_kinematic_splitting"] = row["median.step"] / baseline["median.step"]
        if fresh:
            row["ratio_to_one_fluid_factorization"] = row["median.step"] / fresh
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
