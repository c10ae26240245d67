"""Example 3: step through a run and stop when a probe crosses a threshold.

``ml.steps(case)`` yields every step as it is computed — its time, its
energy ledger, its probes and its state — and writes nothing.  Here the
loop stops as soon as the wall at z = 2 cm has moved outward by 30 µm; the
crossing time is interpolated between the last two steps.  Leaving the loop
ends the run: no later step is computed.

Prints the crossing time in ms (about 3.87 ms on this coarse mesh).
"""

from pathlib import Path

import multilayer as ml

CASES = Path(__file__).resolve().parents[2] / "cases"
THRESHOLD = 30e-4  # cm: 30 µm

case = ml.load_case(CASES / "pulse-koiter.toml", {"mesh.nz": 30, "mesh.nr": 4})

previous = (0.0, 0.0)  # (t, η) of the step before
for step in ml.steps(case):
    eta = step.probes["eta_z2"]
    assert step.ledger["energy.relative_residual"] < 1e-9  # every step closes its energy identity
    if eta > THRESHOLD:
        break
    previous = (step.t, eta)
else:
    raise SystemExit("the threshold was never reached")

t0, eta0 = previous
crossing = t0 + (THRESHOLD - eta0) / (eta - eta0) * (step.t - t0)
print(f"stopped after step {step.n} of {case.time.steps} (t = {1e3 * step.t:.2f} ms)")
crossing_ms = 1e3 * crossing
print(f"eta at z = 2 cm crosses 30 um at t = {crossing_ms:.4f} ms")
