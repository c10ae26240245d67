"""The bundled carotid-like artery (cases/carotid.toml) through its first systole: a flow-driven, three-layer,
Windkessel-loaded tube as a hemodynamics user writes it, run by the default coupler.

What the issue of physiological scenes asked of it (docs/accuracy.md, "The carotid-like artery"): the lumen's
volume follows the flow through its ends, the energy ledger closes, and the stabilized Navier–Stokes centreline
velocity stays within 0 to 2.5 times the section's mean velocity.
"""

import numpy as np
from runs import run_case_file

RADIUS = 0.3  # the lumen at rest (cm)


def test_the_carotid_systole_keeps_volume_energy_and_a_bounded_centreline(tmp_path):
    result, data = run_case_file("carotid", tmp_path, "time.end=0.3")
    assert result.status == "ok", result.reason
    s, summary = data.series, data.summary
    assert summary["energy"]["max_relative_residual"] <= 1e-9
    # measured 7.3e-5 of the volume moved over the whole first cycle (the tube's flux through Γ on the fluid's own
    # domain, theory §7); the paper's Robin term lost half the inflow here
    assert abs(summary["volume"]["relative_drift"]) <= 1e-3, summary["volume"]
    # the inflow is the table's, and it leaves through the Windkessel (no net backflow in this first systole)
    assert np.max(s["q_in"]) > 20.0 and np.min(s["q_out"]) > 0.0
    for probe, section, eta in (("u_axis_z3", "q_mid", "eta_z3"), ("u_axis_z55", "q_out", "eta_z55")):
        mean = s[section] / (np.pi * (RADIUS + s[eta]) ** 2)  # the section as the wall has moved it
        flowing = mean > 5.0
        ratio = s[probe][flowing] / mean[flowing]
        # measured over the first cycle: 0.84–1.47 at z = 3, 0.25–1.52 at z = 5.5 (on 20 × 3 cells: −0.61 to 1.56)
        assert np.all((ratio > 0.0) & (ratio < 2.5)), (probe, ratio.min(), ratio.max())


def test_the_scene_checks_script_reads_the_runs_it_is_given(tmp_path, capsys):
    """scripts/scene_checks.py, which prints the tables of docs/verification.md's carotid studies: its row of a run is that run's
    summary and series, and the change between two runs of one mesh is zero."""
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location("scene_checks", Path(__file__).parents[1] / "scripts" / "scene_checks.py")
    scene_checks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(scene_checks)
    result, data = run_case_file("carotid", tmp_path / "a", "time.end=0.05", "mesh.nz=10", "mesh.nr=2")
    run_case_file("carotid", tmp_path / "b", "time.end=0.05", "mesh.nz=10", "mesh.nr=2")
    assert scene_checks.main([str(tmp_path / "a"), str(tmp_path / "b"), "--radius", "0.3"]) == 0
    out = capsys.readouterr().out
    volume = data.summary["volume"]["relative_drift"]
    assert f"| a | ok | {data.summary['steps']} | " in out and f"{volume:.2e}" in out
    assert "| a → b | 0.00 | 0.00 |" in out
