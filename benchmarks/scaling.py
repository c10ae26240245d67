"""Time per coupled step and peak memory against the number of unknowns, and the fitted exponent.

Not a test: nothing is asserted.  For each mesh (``nz × nr`` fluid cells; the
wall's bands get ``nz`` axial cells as well) it builds the quick-start case
(``cases/pulse-koiter-thick.toml``, kinematic splitting by default) in a
**fresh process** — so that the peak resident memory (``ru_maxrss`` of
``resource.getrusage``) is that mesh's — runs ``--steps`` steps and prints
one JSON object: unknowns (fluid + wall), median seconds per step (the
first step, which factorizes, left out; reported apart), its phases, the
mean step (which counts the steps that refactorize),
factorizations and Krylov iterations, a fresh factorization of the fluid
system timed in the same process — also in GMRES iterations of the run
(``fresh_factorization_in_iterations``: what ``[solver]
factorization_cost`` stands for on this machine) — and peak RSS.  At the
end it prints the
least-squares exponent p of time per step ∝ N^p over the meshes with at
least ``--fit-from`` unknowns.

The fresh factorization is a numeric factorization by the run's own backend
instance, on the ordering the run already keeps for the pattern and in the
run's precision (what a refactorizing step pays; with ``--set
solver.factors=single`` a double-precision one is timed too); ``--colamd`` adds one by SuperLU with its COLAMD
ordering (``superlu-colamd``, what every step paid before the ordering was
kept) and the peak RSS is read before both.  Every step's kernel time
and minor page faults are reported too (``median.system_s``,
``median.page_faults``); ``--keep-freed-memory`` sets glibc's ``mallopt`` so
that freed memory stays in the process, to measure what those faults cost.

    python benchmarks/scaling.py                                   # 5k → ~1e6 unknowns
    python benchmarks/scaling.py --meshes 60x8 120x16 240x32 --steps 6
    python benchmarks/scaling.py --set solver.reuse=none --no-fresh
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

CASE = Path(__file__).parents[1] / "cases" / "pulse-koiter-thick.toml"
MESHES = ("60x8", "120x16", "240x32", "480x64", "960x128")
#: fluid unknowns above which --colamd is skipped: COLAMD's fill at ~1e6 unknowns would need ~20–25 GB
COLAMD_LIMIT = 400_000


def one(mesh: str, steps: int, sets: list[str], fresh: bool, colamd: bool = False) -> dict:
    """Run ``steps`` steps on ``mesh`` in this process; the row to print."""
    from coupled_step import (
        fresh_factorizations_s,  # this script's folder: the fresh factorizations of both
    )

    from multilayer.case.casefile import load_case
    from multilayer.coupling.build import prepare
    from multilayer.numerics.threads import blas_threads
    from multilayer.plugin.registry import Registry

    nz, nr = (int(k) for k in mesh.split("x"))
    registry = Registry.load()
    case = load_case(CASE, [f"mesh.nz={nz}", f"mesh.nr={nr}", "time.end=1", *sets], registry)
    with blas_threads(case.threads):
        t0 = time.perf_counter()
        setup, coupler = prepare(case, registry)
        state = coupler.initial_state(setup)
        build_s = time.perf_counter() - t0
        run = coupler.evolve(setup, state)
        samples = []
        for _ in range(steps):
            before = {**_counters(setup), **_kernel()}
            t0 = time.perf_counter()
            next(run)
            samples.append({"step": time.perf_counter() - t0,
                            **{k: v - before[k] for k, v in {**_counters(setup), **_kernel()}.items()}})
        peak_rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # the run's, before the extras
        # the run's own backend instance (a numeric factorization on the ordering the run already has) and,
        # below the limit, the factorization before the ordering was kept
        colamd = colamd and setup.dof_counts().get("fluid", 0) <= COLAMD_LIMIT
        times = fresh_factorizations_s(setup, colamd) if fresh else {}
        fresh_s, colamd_s = times.get("fresh"), times.get("colamd")
    warm = samples[1:] or samples
    dofs = setup.dof_counts()
    n = dofs.get("fluid", 0) + dofs.get("wall", 0)
    row = {"mesh": mesh, "unknowns": n, "dofs": dofs, "steps": len(warm), "build_s": build_s,
           "first_step_s": samples[0]["step"],
           **{f"median.{k}": statistics.median(s[k] for s in warm) for k in samples[0]},
           "mean.step": statistics.fmean(s["step"] for s in warm),  # the steps that refactorize counted
           "mean.krylov_iterations": statistics.fmean(s["krylov_iterations"] for s in warm),
           "mean.factorizations": statistics.fmean(s["factorizations"] for s in warm),
           "fresh_fluid_factorization_s": fresh_s, "colamd_fluid_factorization_s": colamd_s,
           "peak_rss_mb": peak_rss_mb}
    row["peak_rss_kb_per_unknown"] = row["peak_rss_mb"] * 1024.0 / n
    if fresh_s:
        row["ratio_to_one_fluid_factorization"] = row["median.step"] / fresh_s
        row["mean_ratio_to_one_fluid_factorization"] = row["mean.step"] / fresh_s
        iterations = sum(s["krylov_iterations"] for s in warm)
        if iterations:  # the factorization in GMRES iterations (each with its share of the guess): what
            # [solver] factorization_cost stands for on this machine
            row["fresh_factorization_in_iterations"] = fresh_s * iterations / sum(s["krylov"] for s in warm)
    if colamd_s:
        row["ratio_to_one_colamd_factorization"] = row["median.step"] / colamd_s
    if "double" in times:  # the run's factors are single: also against a double-precision factorization
        row["double_fluid_factorization_s"] = times["double"]
        row["ratio_to_one_double_fluid_factorization"] = row["median.step"] / times["double"]
    return row


def _kernel() -> dict[str, float]:
    """The process's kernel time and minor page faults so far (what fresh memory costs)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return {"system_s": r.ru_stime, "page_faults": float(r.ru_minflt)}


def keep_freed_memory() -> None:
    """glibc only: serve every allocation from the heap and never trim it, so freed memory is reused
    without new page faults (``--keep-freed-memory``: to measure what those faults cost)."""
    import ctypes

    libc = ctypes.CDLL("libc.so.6")
    libc.mallopt(-4, 0)  # M_MMAP_MAX: no mmap'd blocks
    libc.mallopt(-1, 2**62)  # M_TRIM_THRESHOLD: never give the heap's top back


def _counters(setup) -> dict[str, float]:
    stats = [*setup.solvers.values(), setup.fluid.stats]
    t = setup.fluid.timings
    return {"assembly": t["assembly"], "ledger": t["ledger"],
            "factorization": sum(s.factorization_s for s in stats), "solves": sum(s.solve_s for s in stats),
            "krylov": sum(s.krylov_s for s in stats), "factorizations": float(sum(s.factorizations for s in stats)),
            "krylov_iterations": float(sum(s.krylov_iterations for s in stats)),
            "structure": setup.solvers["wall"].solve_s if "wall" in setup.solvers else 0.0}


def exponent(rows: list[dict], start: int) -> float | None:
    """Least-squares slope of log(time per step) against log(unknowns) over rows with ≥ ``start`` unknowns."""
    pts = [(math.log(r["unknowns"]), math.log(r["median.step"])) for r in rows if r["unknowns"] >= start]
    if len(pts) < 2:
        return None
    mx = statistics.fmean(x for x, _ in pts)
    my = statistics.fmean(y for _, y in pts)
    return sum((x - mx) * (y - my) for x, y in pts) / sum((x - mx) ** 2 for x, _ in pts)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="+", default=list(MESHES), metavar="NZxNR")
    ap.add_argument("--steps", type=int, default=4, help="steps per mesh (the first is left out)")
    ap.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--fit-from", type=int, default=20_000, help="fit the exponent from this many unknowns up")
    ap.add_argument("--no-fresh", dest="fresh", action="store_false", help="skip the fresh factorization")
    ap.add_argument("--colamd", action="store_true",
                    help="also time a SuperLU factorization with COLAMD (solver.linear = 'superlu-colamd')")
    ap.add_argument("--keep-freed-memory", action="store_true",
                    help="glibc mallopt: allocations from the heap, never trimmed (measures the page faults' cost)")
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per mesh before giving up")
    ap.add_argument("--one", help=argparse.SUPPRESS)  # internal: run one mesh in this process
    args = ap.parse_args(argv)
    if args.one:
        if args.keep_freed_memory:
            keep_freed_memory()
        print(json.dumps(one(args.one, args.steps, args.sets, args.fresh, args.colamd)), flush=True)
        return 0
    rows = []
    for mesh in args.meshes:
        cmd = [sys.executable, __file__, "--one", mesh, "--steps", str(args.steps),
               *[a for s in args.sets for a in ("--set", s)], *([] if args.fresh else ["--no-fresh"]),
               *(["--colamd"] if args.colamd else []), *(["--keep-freed-memory"] if args.keep_freed_memory else [])]
        try:
            out = subprocess.run(cmd, capture_output=True, text=True, timeout=args.timeout)
        except subprocess.TimeoutExpired:
            print(json.dumps({"mesh": mesh, "error": f"over {args.timeout:.0f} s"}), flush=True)
            break
        if out.returncode != 0:
            print(json.dumps({"mesh": mesh, "error": out.stderr.strip().splitlines()[-1:]}), flush=True)
            break
        rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
        print(json.dumps(rows[-1]), flush=True)
    print(json.dumps({"exponent_from": args.fit_from, "time_per_step_exponent": exponent(rows, args.fit_from)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
