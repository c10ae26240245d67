"""benchmarks/scaling.py end to end on two coarse meshes: the rows it prints are complete and consistent."""

import json
import math
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).parents[1] / "benchmarks" / "scaling.py"


def test_scaling_prints_a_row_per_mesh_and_the_factorization_in_iterations():
    """Nothing timed is asserted: the rows carry every phase, the counts of the run, and a factorization's
    price in GMRES iterations (what ``[solver] factorization_cost`` stands for), which is a fresh
    factorization's seconds over a GMRES iteration's — finite and positive whenever GMRES ran."""
    out = subprocess.run([sys.executable, str(SCRIPT), "--meshes", "30x4", "40x6", "--steps", "15",
                          "--fit-from", "0"], capture_output=True, text=True, check=True)
    lines = [json.loads(line) for line in out.stdout.splitlines()]
    rows, fit = lines[:-1], lines[-1]
    assert [r["mesh"] for r in rows] == ["30x4", "40x6"] and rows[0]["unknowns"] < rows[1]["unknowns"]
    for r in rows:
        assert r["steps"] == 14 and r["mean.krylov_iterations"] > 0
        assert r["fresh_fluid_factorization_s"] > 0 and r["median.step"] > 0
        price = r["fresh_factorization_in_iterations"]
        assert math.isfinite(price) and price > 0
    assert math.isfinite(fit["time_per_step_exponent"])
