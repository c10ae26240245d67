"""Fill, factorization and solve time of the fluid's matrix under each SuperLU ordering; printed as JSON.

Not a test: nothing is asserted.  For each mesh it runs two steps of the
quick-start case (``cases/pulse-koiter-thick.toml``, kinematic splitting)
to get a fluid matrix of a moving wall (free DOFs), then factorizes it

* ``nested-dissection``: the default backend ``superlu`` — METIS nested
  dissection of A + Aᵀ (:mod:`multilayer.numerics.ordering`, its time reported
  apart: a run pays it once per pattern), SuperLU in that order with
  threshold pivoting 1e-3;
* ``colamd``: ``superlu-colamd``, SuperLU's own column ordering;
* ``minimum-degree``: SuperLU's MMD on A + Aᵀ in symmetric mode, threshold 1e-3
  (what SuperLU offers without an outside ordering);

and prints one JSON object per (mesh, ordering): entries of L + U per row,
factorization seconds (median of ``--repeat``), one solve's seconds and the
relative residual of that solve.

    python benchmarks/ordering.py                          # 120x16 240x32 480x64
    python benchmarks/ordering.py --meshes 60x8 120x16 --repeat 3
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse.linalg as spla

CASE = Path(__file__).parents[1] / "cases" / "pulse-koiter-thick.toml"


def fluid_matrix(mesh: str):
    from multilayer.case.casefile import load_case
    from multilayer.coupling.build import prepare
    from multilayer.plugin.registry import Registry

    nz, nr = (int(k) for k in mesh.split("x"))
    registry = Registry.load()
    case = load_case(CASE, [f"mesh.nz={nz}", f"mesh.nr={nr}", "time.end=1"], registry)
    setup, coupler = prepare(case, registry)
    run = coupler.evolve(setup, coupler.initial_state(setup))
    next(run), next(run)
    return setup.fluid.discrete.last_matrix.tocsc()


def measure(A, factor, repeat: int) -> dict:
    b = np.random.default_rng(0).standard_normal(A.shape[0])
    times, lu = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        lu, solve = factor()
        times.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    x = solve(b)
    solve_s = time.perf_counter() - t0
    return {"fill_per_row": (lu.L.nnz + lu.U.nnz) / A.shape[0], "factorization_s": statistics.median(times),
            "solve_s": solve_s, "residual": float(np.linalg.norm(A @ x - b) / np.linalg.norm(b))}


def main(argv: list[str] | None = None) -> int:
    from multilayer.numerics.linsolve import _SuperLU
    from multilayer.numerics.ordering import nested_dissection
    from multilayer.numerics.threads import blas_threads

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="+", default=["120x16", "240x32", "480x64"], metavar="NZxNR")
    ap.add_argument("--repeat", type=int, default=1, help="factorizations per ordering (the median is printed)")
    args = ap.parse_args(argv)
    with blas_threads(1):
        for mesh in args.meshes:
            A = fluid_matrix(mesh)
            t0 = time.perf_counter()
            p = nested_dissection(A)
            ordering_s = time.perf_counter() - t0
            P = A[p][:, p].tocsc()

            def nd():
                lu = spla.splu(P, permc_spec="NATURAL", diag_pivot_thresh=_SuperLU.PIVOT_THRESHOLD,
                               options={"SymmetricMode": True})

                def solve(b):
                    x = np.empty_like(b)
                    x[p] = lu.solve(b[p])
                    return x
                return lu, solve

            def colamd():
                lu = spla.splu(A, permc_spec="COLAMD")
                return lu, lu.solve

            def mmd():
                lu = spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=_SuperLU.PIVOT_THRESHOLD,
                               options={"SymmetricMode": True})
                return lu, lu.solve

            for name, factor in (("nested-dissection", nd), ("colamd", colamd), ("minimum-degree", mmd)):
                row = {"mesh": mesh, "unknowns": A.shape[0], "nnz": A.nnz, "ordering": name,
                       **measure(A, factor, args.repeat)}
                if name == "nested-dissection":
                    row["ordering_s"] = ordering_s
                print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
