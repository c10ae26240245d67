"""Every bundled case runs as it is; the structure-only ones match their exact solutions.

The cases in ``cases/`` double as regression tests (scikit-fem's examples
style): each asserts a scalar the physics fixes.
"""


import numpy as np
import pytest
from runs import CASES, run_cli

from multilayer.commands.main import main
from multilayer.numerics.signals import backward_euler_eigenvalue, prony_roots


def run(case, tmp_path, *sets):
    return run_cli(case, tmp_path / case, *sets)


def semi_discrete_lambda(signal, dt):
    z = prony_roots(np.asarray(signal), 2)
    return backward_euler_eigenvalue(z[np.argmax(np.angle(z))], dt)


@pytest.mark.parametrize("case", sorted(p.stem for p in CASES.glob("*.toml")))
def test_bundled_case_validates(case):
    assert main(["validate", str(CASES / f"{case}.toml")]) == 0


def test_membrane_mode_frequency(tmp_path):
    code, summary, rows = run("membrane-mode", tmp_path)
    assert code == 0 and summary["status"] == "ok"
    assert summary["factorizations"] == {"wall": 1}
    assert summary["energy"]["max_relative_residual"] < 1e-10
    # ω₁² = C1 k²/(ρh), k = π/L; P2 on 64 cells: the semi-discrete error is ~1e-8
    lam = semi_discrete_lambda([float(r["eta_mid"]) for r in rows], 2e-5)
    exact = np.pi / 6.0 * np.sqrt(2.0e4 / (1.1 * 0.1))
    assert abs(abs(lam.imag) - exact) / exact < 1e-6
    assert abs(lam.real) < 1e-6 * exact  # undamped: BE's damping is removed by the inversion


def test_koiter_damped_mode_matches_damped_dispersion_relation(tmp_path):
    code, summary, rows = run("koiter-damped-mode", tmp_path)
    assert code == 0 and summary["energy"]["max_relative_residual"] < 1e-10
    from multilayer_plugins.thin_shell import koiter_coefficients
    rho_h, R, L = 1.1 * 0.1, 0.5, 6.0
    C0, C1, C2 = koiter_coefficients(0.1, 7.5e5, 0.45, R)
    D0, D1, D2 = koiter_coefficients(0.1, 200.0, 0.45, R)
    k = 2 * np.pi / L
    exact = np.roots([rho_h, D0 + D1 * k**2 + D2 * k**4, C0 + C1 * k**2 + C2 * k**4])
    exact = exact[np.argmax(exact.imag)]
    lam = semi_discrete_lambda([float(r["eta_quarter"]) for r in rows], 1e-5)
    assert abs(lam - exact) / abs(exact) < 1e-5
    assert lam.real < 0


def test_band_sliding_mode_frequency(tmp_path):
    code, summary, rows = run("band-sliding-mode", tmp_path)
    assert code == 0 and summary["energy"]["max_relative_residual"] < 1e-10
    E, nu, rho, L, H = 1e6, 0.3, 1.1, 2.0, 0.5
    mu, lam_ = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    exact = np.sqrt((lam_ + 2 * mu) / rho) * np.pi * np.hypot(1 / L, 1 / H)
    lam = semi_discrete_lambda([float(r["dr"]) for r in rows], 2e-6)
    # P2, 16 × 8 cells: the eigenvalue error is O(h⁴) ≈ 1e-4 here (test_thick_band.py)
    assert abs(abs(lam.imag) - exact) / exact < 3e-4


def test_four_layer_wall_ledger_and_outputs(tmp_path):
    code, summary, rows = run("four-layer-wall", tmp_path)
    assert code == 0
    assert summary["energy"]["max_relative_residual"] < 1e-10
    assert max(float(r["energy.relative_residual"]) for r in rows) < 1e-10
    assert summary["steps"] == len(rows) == 300
    assert {"assembly", "factorization", "solves", "output"} <= set(summary["timings"])
    out = tmp_path / "four-layer-wall"
    assert len(list(out.glob("wall_*.vtu"))) == 300 // 30 + 1
    # the pulse pushes the lumen out, and the lamina follows it
    assert max(float(r["eta_lumen_3"]) for r in rows) > 0
    assert max(float(r["eta_lamina_3"]) for r in rows) > 0


#: peak η (µm) at z = 1, 2, 3, 4 cm of cases/quick-start.toml at Δt = 6.25e-6 (16× finer), measured with
#: ``multilayer run cases/quick-start.toml --out ref16 --set time.dt=6.25e-6``; at Δt = 1.25e-5 (8×) the
#: peaks differ from these by < 0.004 %, so they are the converged answer of the scene's mesh.
QUICK_START_REFERENCE = (536.45, 476.28, 440.87, 437.60)


def test_the_quick_start_answer_is_right(tmp_path):
    """The README's main job: its peaks within 0.3 % of the 16× finer run (measured: 0.016, 0.0005, 0.008,
    0.28 %; the paper's first-order scheme at its Δt is 54–95 % low), the ledger closed, the pulse past z = 4."""
    code, summary, rows = run("quick-start", tmp_path)
    assert code == 0 and summary["steps"] == 300
    assert summary["scheme"] == {"name": "crank-nicolson", "order": 2}
    assert summary["energy"]["max_relative_residual"] < 1e-11
    for k, ref in enumerate(QUICK_START_REFERENCE, start=1):
        eta = np.array([float(r[f"eta_z{k}"]) for r in rows]) * 1e4
        assert abs(eta.max() / ref - 1) < 3e-3, (k, eta.max(), ref)
        assert eta[-1] < 0.5 * eta.max() or k == 4  # the crest has passed z = 1, 2, 3 cm


def test_aortic_inflow_puts_its_stroke_volume_in_and_the_pressure_follows(tmp_path):
    """physiological-flow, one cycle on a coarse mesh: the inflow's flux is the table's, every level (its volume
    over the cycle is the table's mean, 0.75 cm² per unit depth, to the trapezoid rule's error on a smooth periodic
    spline); the ledger closes; the inlet pressure rises from its diastolic 80 mmHg (scaled) over the ejection."""
    code, summary, rows = run("physiological-flow", tmp_path, "mesh.nz=15", "mesh.nr=3", "time.end=1.0",
                              "time.dt=4e-3")
    assert code == 0 and summary["status"] == "ok", summary["reason"]
    assert summary["energy"]["max_relative_residual"] < 1e-9
    t = np.array([0.0] + [float(r["t"]) for r in rows])
    q = np.array([0.0] + [float(r["q_in"]) for r in rows])
    assert abs(np.trapezoid(q, t) - 0.75) < 1e-8  # measured 2.9e-10
    p = np.array([float(r["end.inlet.p"]) for r in rows])
    assert p.max() > 1.5 * 2666.4 and abs(p[0] - 2666.4) < 0.01 * 2666.4


@pytest.mark.slow
def test_artery_hgo_starts_in_equilibrium_under_its_diastolic_pressure(tmp_path):
    """``cases/artery-hgo.toml`` held at its 80 mmHg at both ends, no flow, to 2 ms: the prestressed wall keeps
    its imaged geometry (measured: peak |η| 4.2e-15 cm), the fluid stays at rest (|Q| ≤ 2.2e-11 mL/s).  Most
    of its time is the stress-free reference, found at validation and again by the run."""
    code, summary, rows = run("artery-hgo", tmp_path, "time.end=2e-3", "loads.inlet=1.0666e5", "loads.outlet=1.0666e5")
    assert code == 0 and summary["status"] == "ok"
    assert summary["steps"] >= 2 and summary["energy"]["max_relative_residual"] < 1e-10
    eta = max(abs(float(r[name])) for r in rows for name in ("eta_z1", "eta_z3", "eta_z5"))
    assert eta < 1e-12, eta  # cm: the lumen moves by round-off, against a pulse's 1e-2
    assert max(abs(float(r["q_in"])) for r in rows) < 1e-9
