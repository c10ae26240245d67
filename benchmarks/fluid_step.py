"""Seconds per phase of one fluid step (A2) against the mesh size, printed as JSON.

Not a test: nothing is asserted.  For each mesh and each linear solver
installed (``multilayer.numerics.linsolve.BACKENDS``) it times

* ``ns-coupled``: Navier–Stokes, coupled wall with a dummy thin layer
  (Robin mass ρ₁h ∫vψ, a given v^{n+½}), a deformed channel: the Oseen
  matrix changes every step, so every step assembles and factorizes;
* ``stokes-rigid``: Stokes on a rigid wall, a constant matrix factorized in
  the first step only (its factorization column is that one factorization).

and prints one JSON object per (mesh, mode, solver) with the medians over the
steps of the phases of a step (seconds, differences of the fluid's counters).  The first step of
every run is a warm-up and is left out of the medians; its factorization is
reported apart (``first_factorization``): for ``pardiso`` it includes the
symbolic analysis (ordering), which later steps of the same pattern reuse.

    python benchmarks/fluid_step.py                       # the table of docs/performance.md
    python benchmarks/fluid_step.py --meshes 60x10 120x20 --steps 5 --solvers superlu
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import time

import numpy as np
import scipy
from skfem import BilinearForm, asm

from multilayer.fluid.contract import Domain, FluidSetup, Interface
from multilayer.functions.loads import ConstantPressure
from multilayer.numerics.linsolve import BACKENDS
from multilayer.numerics.timescheme import named
from multilayer_plugins.channel import NavierStokes, Stokes
from multilayer_plugins.planar import Planar
from multilayer_plugins.pressure import PressureEnd

#: P_in = 1000 dyn/cm², P_out = 0
ENDS = {"inlet": PressureEnd(ConstantPressure(1.0e3)), "outlet": PressureEnd(ConstantPressure(0.0))}

L, R, MU, RHO, DT = 6.0, 0.5, 0.035, 1.0, 1e-4
THIN_MASS = 1.1 * 0.1  # ρ₁h (g/cm²) of the dummy thin layer
PHASES = ("assembly", "factorization", "solve", "ledger")
BE = named("backward-euler")


def counters(fluid) -> dict[str, float]:
    st, t = fluid.stats, fluid.timings
    return {"assembly": t["assembly"], "factorization": st.factorization_s, "solve": st.solve_s, "ledger": t["ledger"]}


def timed_step(fluid, *args, **kwargs):
    """One fluid step and the seconds of each phase (differences of the fluid's counters)."""
    before = counters(fluid)
    solution, _ = fluid.step(*args, **kwargs)
    after = counters(fluid)
    return solution, {k: after[k] - before[k] for k in PHASES}


@BilinearForm
def line_mass(v, psi, w):
    return v * psi


def ns_coupled(nz: int, nr: int, order: int, solver: str, steps: int) -> tuple[int, list[dict]]:
    fluid = NavierStokes(RHO, MU)
    fluid.setup(FluidSetup(Planar(), L, R, nz, nr, order, 1.0, wall="coupled", solver=solver, ends=ENDS))
    M = THIN_MASS * asm(line_mass, fluid.line.basis)
    robin = M / DT
    z = fluid.line.z
    eta = 0.01 * np.sin(np.pi * z / L)
    state = fluid.initial_state(lambda zz, rr: (5.0 * (1 - (rr / R) ** 2), 0 * rr), eta)
    timings = []
    for n in range(steps):
        v_half = 2.0 * np.sin(np.pi * z / L) * np.cos(0.3 * n)
        v_half[fluid.line.end_dofs] = 0.0
        solution, phases = timed_step(fluid, [state], Domain(eta, v_half), BE, DT, (0.0, DT),
                                      Interface(robin, robin @ v_half), eta, eta + DT * v_half)
        state, eta = solution.state, eta + DT * v_half
        timings.append(phases)
    return fluid.channel.ndofs, timings


def stokes_rigid(nz: int, nr: int, order: int, solver: str, steps: int) -> tuple[int, list[dict]]:
    fluid = Stokes(RHO, MU)
    fluid.setup(FluidSetup(Planar(), L, R, nz, nr, order, 1.0, wall="rigid", solver=solver, ends=ENDS))
    state = fluid.initial_state()
    still = Domain.still(fluid.line.ndofs)
    timings = []
    for _ in range(steps):
        solution, phases = timed_step(fluid, [state], still, BE, DT, (0.0, DT))
        state = solution.state
        timings.append(phases)
    assert fluid.discrete.stats.factorizations == 1
    return fluid.channel.ndofs, timings


def row(mesh: str, mode: str, solver: str, ndofs: int, timings: list[dict], wall_s: float) -> dict:
    warm = timings[1:] or timings
    out = {"mesh": mesh, "unknowns": int(ndofs), "mode": mode, "solver": solver, "steps": len(timings)}
    for k in PHASES:
        out[k] = statistics.median(t[k] for t in warm)
    out["first_factorization"] = timings[0]["factorization"]
    if mode == "stokes-rigid":
        out["factorization"] = timings[0]["factorization"]  # the only one
    out["total"] = statistics.median(sum(t[k] for k in PHASES) for t in warm)
    out["run_s"] = wall_s
    return out


def machine() -> dict:
    cpu = "unknown"
    try:
        with open("/proc/cpuinfo") as fh:
            cpu = next(line.split(":", 1)[1].strip() for line in fh if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    import os

    return {"nproc": os.cpu_count(), "cpu": cpu, "python": platform.python_version(),
            "numpy": np.__version__, "scipy": scipy.__version__, "solvers": sorted(BACKENDS)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="+", default=["60x10", "120x20", "240x40", "480x60"], help="NZxNR")
    ap.add_argument("--order", type=int, default=2)
    ap.add_argument("--steps", type=int, default=4, help="steps per run (the first is a warm-up)")
    ap.add_argument("--solvers", nargs="+", default=sorted(BACKENDS))
    ap.add_argument("--modes", nargs="+", default=["ns-coupled", "stokes-rigid"])
    args = ap.parse_args(argv)
    runs = {"ns-coupled": ns_coupled, "stokes-rigid": stokes_rigid}
    print(json.dumps({"machine": machine()}), flush=True)
    for mesh in args.meshes:
        nz, nr = (int(s) for s in mesh.split("x"))
        for mode in args.modes:
            for solver in args.solvers:
                t0 = time.perf_counter()
                ndofs, timings = runs[mode](nz, nr, args.order, solver, args.steps)
                print(json.dumps(row(mesh, mode, solver, ndofs, timings, time.perf_counter() - t0)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
