"""How close GMRES's start is to each step's solution: the residual of candidate guesses, printed as JSON.

Not a test: nothing is asserted.  One coupler runs the case (by default the
quick-start pulse, kinematic splitting) and every new matrix its
:class:`~multilayer.numerics.linsolve.ReusingSolver` solves is also handed to the
candidates, each built from the run's own earlier solutions:

* ``polynomial-p``: the value at the next step of the polynomial of degree p
  through the last p + 1 solutions (p = 1: 2xⁿ − x^{n−1}; p = 2, the guess
  of earlier rounds: 3xⁿ − 3x^{n−1} + x^{n−2});
* ``span-k``: the least-residual combination of the last k solutions
  (:class:`multilayer.numerics.krylov.SolutionSpan`, the solver's guess with k =
  ``ReusingSolver.GUESS_SPAN``).

For each it prints the median and the largest relative residual
‖b − A x₀‖₂ / ‖b‖₂ over the steps from ``--from`` on (every candidate has
its solutions by then), and the run's own GMRES iterations a step.

    python benchmarks/guess.py                                   # 120 × 16 cells (22k unknowns), 120 steps
    python benchmarks/guess.py --set 'coupler={model="monolithic",scheme="crank-nicolson"}'
"""

from __future__ import annotations

import argparse
import json
import statistics
from math import comb
from pathlib import Path

import numpy as np

from multilayer.case.casefile import load_case
from multilayer.coupling.build import prepare
from multilayer.numerics.krylov import SolutionSpan
from multilayer.numerics.linsolve import ReusingSolver
from multilayer.numerics.threads import blas_threads
from multilayer.plugin.registry import Registry

CASE = Path(__file__).parents[1] / "cases" / "pulse-koiter-thick.toml"
DEGREES = (1, 2, 3, 4, 5)
SPANS = (3, 4, 6, 8, 12, 16)


def extrapolated(solutions: list[np.ndarray], degree: int) -> np.ndarray:
    """x^{n+1} of the polynomial through the last degree + 1 solutions: Σ_j (−1)^{j+1} C(p+1, j) x^{n+1−j}."""
    return sum((-1) ** (j + 1) * comb(degree + 1, j) * solutions[-j] for j in range(1, degree + 2))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--case", type=Path, default=CASE)
    parser.add_argument("--set", action="append", default=["mesh.nz=120", "mesh.nr=16"], metavar="KEY=VALUE")
    parser.add_argument("--steps", type=int, default=120)
    parser.add_argument("--from", dest="first", type=int, default=max(SPANS) + 1,
                        help="the first new matrix counted, from 1 (default: once every candidate has its solutions)")
    args = parser.parse_args(argv)
    if args.first < max(DEGREES) + 2:
        parser.error(f"--from {args.first}: expected at least {max(DEGREES) + 2} (the degree-{max(DEGREES)} "
                     f"extrapolation needs {max(DEGREES) + 1} earlier solutions)")
    registry = Registry.load()
    case = load_case(args.case, args.set, registry)
    setup, coupler = prepare(case, registry)
    histories: dict[int, list[np.ndarray]] = {}  # per solver: its new matrices' solutions, newest last
    residuals: dict[str, list[float]] = {}
    iterations: list[int] = []
    new: dict[int, int] = {}  # per solver: new matrices solved
    solve = ReusingSolver.solve

    def recording(solver, A, b, key=None):
        again = solver.repeats(A, key)  # a sub-iteration's matrix: not a new one
        history = histories.setdefault(id(solver), [])
        counted = not again and new.get(id(solver), 0) + 1 >= args.first  # this new matrix's number, from 1
        if counted:
            norm_b = np.linalg.norm(b)
            guesses = {f"polynomial-{p}": extrapolated(history, p) for p in DEGREES}
            for k in SPANS:
                span = SolutionSpan(k)
                for x in history[-k:]:
                    span.add(x)
                guesses[f"span-{k}"] = span.guess(A, b)
            for name, x0 in guesses.items():
                residuals.setdefault(name, []).append(float(np.linalg.norm(b - A @ x0) / norm_b))
        before = solver.stats.krylov_iterations
        x = solve(solver, A, b, key)
        if not again:
            history[:] = [*history[-max(SPANS):], x]
            new[id(solver)] = new.get(id(solver), 0) + 1
            if counted:
                iterations.append(solver.stats.krylov_iterations - before)
        return x

    ReusingSolver.solve = recording
    try:
        with blas_threads(1):
            steps = coupler.evolve(setup, coupler.initial_state(setup))
            for _ in range(args.steps):
                next(steps)
    finally:
        ReusingSolver.solve = solve
    print(json.dumps({
        "case": str(args.case), "sets": args.set, "steps": args.steps, "counted_from": args.first,
        "counted": len(next(iter(residuals.values()), [])),
        "median_relative_residual": {k: statistics.median(v) for k, v in residuals.items()},
        "max_relative_residual": {k: max(v) for k, v in residuals.items()},
        "gmres_iterations_per_step": statistics.fmean(iterations) if iterations else None,
    }))


if __name__ == "__main__":
    main()
