"""The campaign commands take a tube as they take the channel (issue: "every coupler and command works in both
geometries unchanged"): compare puts planar beside axisymmetric on one scene, stability maps the tube, study
and sweep run it.  Coarse settings (12 × 3 cells, a few ms), so each command's own checks are what is tested:
the numbers' physics is in tests/test_axisymmetric_coupled.py and tests/test_moens_korteweg.py.
"""

import csv
import json

from runs import CASES

from multilayer.commands.main import main

TUBE = CASES / "pulse-koiter-thick-axisymmetric.toml"
COARSE = ["--set", "mesh.nz=12", "--set", "mesh.nr=3"]


def test_compare_puts_the_channel_beside_the_tube(tmp_path):
    """Same mesh and wall; the tube's band has hoop stiffness, so its lumen moves less (at 1 ms: 54 µm against
    the channel's 102 µm at z = 1 cm here)."""
    out = tmp_path / "cmp"
    assert main(["compare", str(CASES / "pulse-koiter-thick.toml"), str(TUBE), "--out", str(out), *COARSE,
                 "--set", "time.end=0.001"]) == 0
    planar, tube = json.loads((out / "report.json").read_text())["variants"]
    assert planar["status"] == tube["status"] == "ok" and planar["dofs_total"] == tube["dofs_total"]
    assert 0 < tube["probes"]["eta_z1"]["peak"] < 0.7 * planar["probes"]["eta_z1"]["peak"]
    assert "pulse-koiter-thick-axisymmetric" in (out / "report.md").read_text()


def test_stability_maps_the_tube(tmp_path):
    out = tmp_path / "stab"
    assert main(["stability", str(TUBE), "--out", str(out), *COARSE, "--set", "time.end=0.001",
                 "--couplers", "kinematic-splitting,monolithic", "--ratios", "1,0.001"]) == 0
    runs = json.loads((out / "stability.json").read_text())["runs"]
    assert len(runs) == 4 and all(r["status"] == "ok" and r["stable"] for r in runs)


def test_study_orders_the_tube_runs(tmp_path):
    """Errors against the finest run fall with Δt (monolithic CN; at 12 × 3 cells and 6 ms still before the
    asymptotic range: 0.88, 0.49, 0.14)."""
    out = tmp_path / "study"
    assert main(["study", str(TUBE), "--out", str(out), *COARSE, "--set", "time.end=0.006",
                 "--set", 'coupler={model="monolithic",scheme="crank-nicolson"}',
                 "--vary", "time.dt=4e-4,2e-4,1e-4,5e-5"]) == 0
    runs = json.loads((out / "study.json").read_text())["runs"]
    assert all(r["status"] == "ok" for r in runs)
    errors = [r["error"] for r in runs[:-1]]
    assert errors == sorted(errors, reverse=True) and errors[-1] < 0.2


def test_sweep_runs_the_tube(tmp_path):
    """A stiffer band moves the lumen less once the pulse has reached z = 1 (measured at 3 ms: 76 and 35 µm; at
    1 ms the stiffer wall's faster wave has arrived and the softer's not); neither run is far enough along for an
    arrival at the last probes, so no speed."""
    out = tmp_path / "sweep"
    assert main(["sweep", str(TUBE), "--out", str(out), *COARSE, "--set", "time.end=0.003", "--jobs", "1",
                 "--vary", "layers[1].young=2e6,8e6"]) == 0
    with open(out / "sweep.csv") as fh:
        soft, stiff = csv.DictReader(fh)
    assert soft["status"] == stiff["status"] == "ok"
    assert float(stiff["peak_eta.eta_z1"]) < 0.5 * float(soft["peak_eta.eta_z1"])
    assert soft["wave_speed"] == stiff["wave_speed"] == ""
    assert float(soft["max_relative_residual"]) < 1e-9 and float(stiff["max_relative_residual"]) < 1e-9
