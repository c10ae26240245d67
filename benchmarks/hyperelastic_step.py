"""Seconds per coupled step of a tube with hyperelastic bands against the same tube with linear ones; JSON.

Not a test: nothing is asserted.  The carotid-like tube of
``tests/test_hyperelastic.py`` (6 cm, R = 0.3 cm, 12 × 3 cells, P2; an
intima shell, a ``neo-hookean`` media with E = 4e6 dyn/cm², σ = 0.45 at rest
and, outside, an ``hgo`` band of the rabbit's media), under a pressure pulse
from its static start at 75 mmHg, runs side by side with the same mesh and
layers made ``linear-elastic`` with the bands' moduli at rest (their μ and κ).
The variants take their steps in turn (step 1 of each, then step 2 of each,
...), so the load of a shared machine falls on both alike.  Per variant it
prints the median over the steps (the first, a warm-up, left out) of the
wall time of a step and of its phases (``benchmarks/coupled_step.py``'s
counters: assembly, factorizations and solves of each system, the ledger),
the wall's Newton corrections per step, and the ratio of the step to the
linear one's.

    python benchmarks/hyperelastic_step.py                               # monolithic Crank–Nicolson, 40 steps
    python benchmarks/hyperelastic_step.py --coupler '{"model": "kinematic-splitting", "robin": "inertia"}'
"""

from __future__ import annotations

import argparse
import copy
import json
import statistics
import sys
import tempfile
import time

from coupled_step import counters

from multilayer.case.casefile import validate_data
from multilayer.coupling.build import prepare
from multilayer.numerics.threads import blas_threads
from multilayer.plugin.registry import Registry

#: the rabbit carotid's media (Holzapfel, Gasser & Ogden 2000) in CGS, κ = 10³ c (band.MEDIA)
MEDIA = {"density": 1.1, "shear_modulus": 3.0e4, "bulk_modulus": 3.0e7, "fibre_modulus": 2.3632e4,
         "fibre_exponent": 0.8393, "fibre_angle": 29.0}
INTIMA = {"model": "koiter-shell", "density": 1.06, "thickness": 0.005, "young": 2.0e6, "poisson": 0.45}
#: (neo-Hookean media, HGO outer band) and their linear twins: E = 9κμ/(3κ + μ), σ = (3κ − 2μ)/(2(3κ + μ))
HYPERELASTIC = [INTIMA,
                {"model": "neo-hookean", "density": 1.1, "thickness": 0.05, "shear_modulus": 1.3793e6,
                 "bulk_modulus": 1.3333e7, "cells": 2},
                {"model": "hgo", **MEDIA, "thickness": 0.03, "cells": 1}]


def twin(mu: float, kappa: float) -> dict[str, float]:
    """The Young's modulus and Poisson ratio of the shear modulus ``mu`` and the bulk modulus ``kappa``."""
    return {"young": 9.0 * kappa * mu / (3.0 * kappa + mu), "poisson": (3.0 * kappa - 2.0 * mu) / (2.0 * (3.0 * kappa + mu))}


LINEAR = [INTIMA,
          {"model": "linear-elastic", "density": 1.1, "thickness": 0.05, **twin(1.3793e6, 1.3333e7), "cells": 2},
          {"model": "linear-elastic", "density": 1.1, "thickness": 0.03, **twin(3.0e4, 3.0e7), "cells": 1}]
TUBE = {"geometry": {"model": "axisymmetric", "length": 6.0, "radius": 0.3},
        "mesh": {"nz": 12, "nr": 3, "order": 2},
        "fluid": {"model": "navier-stokes", "density": 1.06, "viscosity": 0.035},
        "initial": {"pressure": 1.0e5},
        "loads": {"inlet": "1.0e5 + 6.5e3*(1 - cos(2*pi*t/5e-3))", "outlet": 1.0e5}}


def newton_iterations(setup) -> float:
    """The Newton corrections of every system of the run so far (the static start's left out)."""
    return float(sum(st.newton_iterations for name, st in setup.solvers.items() if name != "static"))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--coupler", default='{"model": "monolithic", "scheme": "crank-nicolson"}',
                    help="the [coupler] table, as JSON")
    ap.add_argument("--steps", type=int, default=40, help="steps per variant (the first is a warm-up)")
    ap.add_argument("--dt", type=float, default=1e-3)
    args = ap.parse_args(argv)
    registry = Registry.load()
    runs = {}
    workdir = tempfile.mkdtemp(prefix="hyperelastic_step")
    for label, layers in (("linear", LINEAR), ("hyperelastic", HYPERELASTIC)):
        data = {**copy.deepcopy(TUBE), "layers": copy.deepcopy(layers), "coupler": json.loads(args.coupler),
                "time": {"end": (args.steps + 1) * args.dt, "dt": args.dt}}
        case = validate_data(data, workdir, registry)
        setup, coupler = prepare(case, registry)
        runs[label] = {"setup": setup, "steps": coupler.evolve(setup, coupler.initial_state(setup)), "samples": []}
    for _ in range(args.steps):
        for run in runs.values():
            setup = run["setup"]
            before, corrections = counters(setup), newton_iterations(setup)
            with blas_threads(setup.case.threads):
                t0 = time.perf_counter()
                next(run["steps"])
                wall = time.perf_counter() - t0
            after = counters(setup)
            run["samples"].append({"step": wall, "newton_iterations": newton_iterations(setup) - corrections,
                                   **{k: after[k] - before.get(k, 0.0) for k in after}})
    rows = {}
    for label, run in runs.items():
        warm = run["samples"][1:] or run["samples"]
        keys = sorted({k for s in warm for k in s})
        row = {"variant": label, "coupler": json.loads(args.coupler), "dofs": run["setup"].dof_counts(),
               "steps": len(warm)}
        row.update({f"median.{k}": statistics.median(s.get(k, 0.0) for s in warm) for k in keys})
        row["mean.step"] = statistics.fmean(s["step"] for s in warm)
        row["mean.newton_iterations"] = statistics.fmean(s["newton_iterations"] for s in warm)
        rows[label] = row
    for row in rows.values():
        row["ratio_to_linear"] = row["median.step"] / rows["linear"]["median.step"]
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
