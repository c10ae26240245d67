"""Example 1: run a case in memory and read its energy ledger.

The quick-start scene (a pressure pulse through a channel whose wall is a
Koiter shell on a thick elastic band) on a coarse mesh for 40 steps, run
without a results folder.  Every step closes the discrete energy identity
E^{n+1} - E^n - work + dissipation = 0 (docs/theory.md §7); the run's
``series`` hold every term, so the budget of the whole run can be checked
here in a few lines.

Prints the largest relative residual of the ledger over the run (round-off:
a few 1e-13).
"""

from pathlib import Path

import numpy as np

import multilayer as ml

CASES = Path(__file__).resolve().parents[2] / "cases"  # the bundled cases of the repository

# A coarse mesh and a short run: 40 steps of 1e-4 s (the full case is 60 x 10 cells, 120 steps).
case = ml.load_case(CASES / "pulse-koiter-thick.toml", {"mesh.nz": 30, "mesh.nr": 4, "time.end": 0.004})
res = ml.run(case)  # no `out`: nothing is written to disk
assert res.ok, res.reason

# The ledger's columns: stored energy by part, work by load, dissipation by mechanism.
s = res.series
work = sum(s[c] for c in s if c.startswith("work."))
dissipation = sum(s[c] for c in s if c.startswith("dissipation."))
print(f"{res.steps} steps, {sum(res.summary['dofs'].values())} unknowns")
print(f"energy at the end   {s['energy.total'][-1]:.6e}")
print(f"work put in         {work.sum():.6e}")
print(f"dissipated          {dissipation.sum():.6e}")

# The scene starts at rest (E(0) = 0), so the whole run's budget is E(T) = work - dissipation.
budget = s["energy.total"][-1] - work.sum() + dissipation.sum()
print(f"E(T) - W + D = {budget:.3e} ({budget / work.sum():.1e} of the work)")

max_relative_residual = float(np.max(s["energy.relative_residual"]))
print(f"largest relative residual of a step: {max_relative_residual:.2e}")
