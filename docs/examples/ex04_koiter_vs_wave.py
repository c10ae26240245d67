"""Example 4: the same pulse against two wall models, a Koiter shell and a wave membrane.

One scene, one loop: the first layer is replaced by a whole table (a model
and its parameters) through the overrides, as ``--set 'layers[0]={...}'``
or ``multilayer compare --vary`` would do.  The shell holds the wall by
its hoop stiffness (C0 η), the membrane only by its tension along z (C1 η_zz):
the same pulse lifts them differently.

Prints the ratio of the peak η at z = 1 cm, membrane over shell (about 0.63).
"""

from pathlib import Path

import multilayer as ml

CASES = Path(__file__).resolve().parents[2] / "cases"

walls = {
    "koiter-shell": {"model": "koiter-shell", "density": 1.1, "thickness": 0.1, "young": 7.5e5, "poisson": 0.49},
    "wave-membrane": {"model": "wave-membrane", "density": 1.1, "thickness": 0.1, "tension": 2e5},
}
peaks = {}
for name, layer in walls.items():
    case = ml.load_case(CASES / "pulse-koiter.toml",
                        {"layers[0]": layer, "mesh.nz": 30, "mesh.nr": 4, "time.end": 0.006})
    res = ml.run(case)
    assert res.ok, res.reason
    peaks[name] = res.peaks["eta_z1"]
    print(f"{name:14s} peak eta at z = 1 cm: {1e4 * peaks[name]:7.2f} um, "
          f"ledger {res.max_relative_residual:.1e}")

ratio = peaks["wave-membrane"] / peaks["koiter-shell"]
print(f"membrane / shell: {ratio:.4f}")
