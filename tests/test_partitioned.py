"""The classic partitioned couplers (Dirichlet–Neumann, explicit and sub-iterated) and runs that blow up.

A converged implicit Dirichlet–Neumann step solves the monolithic step's
equations (same scheme, same predicted domain), so the two must agree to
the sub-iteration tolerance; explicit Dirichlet–Neumann is unstable when
the wall is light (Causin, Gerbeau & Nobile 2005) and must stop cleanly.
"""

import json

import numpy as np
import pytest
from runs import CASES, run_cli

from multilayer.commands.main import main
from multilayer.numerics.timescheme import schemes
from multilayer.runner.loop import EnergyBound, RunFailed

TINY = ("geometry.length=2.0", "mesh.nz=8", "mesh.nr=2", "time.end=0.002",
        'output.probes=[{ name = "eta_z1", quantity = "eta", z = 1.0 }]')
#: layers[0].density of pulse-koiter (h = 0.1, R = 0.5, ρ_f = 1) for ρ₁h/(ρ_f R) = 1, 0.1, 0.01, 0.001
DENSITY = {1.0: 5.0, 0.1: 0.5, 0.01: 0.05, 0.001: 0.005}
HEAVY = 50.0  #: ρ₁h/(ρ_f R) = 10


def run(tmp_path, coupler, ratio=None, *sets):
    extra = (f"layers[0].density={DENSITY[ratio]}",) if ratio is not None else ()
    code, summary, rows = run_cli("pulse-koiter", tmp_path / "run", *TINY, *extra, *sets, f"coupler={coupler}")
    cols = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]} if rows else {}
    return code, summary, cols


@pytest.mark.parametrize("scheme", sorted(n for n, s in schemes().items() if len(s.stages) == 1))  # every registered
# scheme Dirichlet–Neumann steps (a single stage a step)
@pytest.mark.parametrize("acceleration", ["iqn-ils", "aitken"])
def test_implicit_dirichlet_neumann_converges_to_the_monolithic_step(tmp_path, scheme, acceleration):
    code, summary, dn = run(tmp_path / "dn", f'{{model="dirichlet-neumann-implicit",scheme="{scheme}",'
                                             f'acceleration="{acceleration}",tolerance=1e-11}}')
    assert code == 0
    _, _, mono = run(tmp_path / "mono", f'{{model="monolithic",scheme="{scheme}"}}')
    gap = np.max(np.abs(dn["eta_z1"] - mono["eta_z1"])) / np.max(np.abs(mono["eta_z1"]))
    assert gap < 1e-8, gap  # measured ~1e-12 (the tolerance is on the interface velocity)
    assert np.all(dn["energy.relative_residual"] <= 1e-9)
    # converged: the interface creates no energy beyond the tolerance
    assert np.max(np.abs(dn["dissipation.interface"])) <= 1e-8 * np.max(np.abs(dn["work.inlet"]))
    assert np.all(dn["iterations"] >= 2) and summary["iterations"]["max"] == dn["iterations"].max()


def test_explicit_dirichlet_neumann_is_stable_for_a_heavy_wall_and_fails_cleanly_for_a_light_one(tmp_path):
    """Measured on this 8 × 2 channel: stable at ρ₁h/(ρ_f R) = 10 (energy 2.8e-8 below the bound);
    at 1 its energy outgrows the work put in by a factor 1600 in 20 steps, at 0.1 the wall blows out."""
    # the fluid takes the wall's old velocity, the wall moves at its new one: the volume lags a step (theory §7)
    code, summary, s = run(tmp_path / "heavy", '"dirichlet-neumann-explicit"', None, f"layers[0].density={HEAVY}",
                           "solver.volume_margin=2")
    assert code == 0 and summary["steps"] == 20
    assert np.all(s["iterations"] == 1) and np.all(s["energy.relative_residual"] <= 1e-9)
    # the energy it creates at the interface is what makes it unstable: nonzero even when stable
    assert np.max(np.abs(s["dissipation.interface"])) > 0
    for ratio in (1.0, 0.1):
        code, summary, s = run(tmp_path / f"light-{ratio}", '"dirichlet-neumann-explicit"', ratio)
        assert code == 1 and summary["status"] == "failed"
        assert "t = " in summary["reason"] and ("blow-out" in summary["reason"] or "energy" in summary["reason"])
        assert 0 < summary["steps"] < 20 and len(s["t"]) == summary["steps"]  # the rows so far are kept


def test_sub_iterations_that_do_not_converge_stop_the_run(tmp_path):
    out = tmp_path / "stuck"
    argv = ["run", str(CASES / "pulse-koiter.toml"), "--out", str(out)]
    for s in (*TINY, f"layers[0].density={DENSITY[0.01]}",
              'coupler={model="dirichlet-neumann-implicit",acceleration="aitken",max_iterations=5}'):
        argv += ["--set", s]
    assert main(argv) == 1
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["steps"] == 0
    assert "did not converge in 5 iterations at t = 0.0001 s" in summary["reason"]


def test_a_wall_blown_outward_stops_the_run(tmp_path):
    """The bound is configurable: [solver] max_displacement (a fraction of R)."""
    code, summary, s = run(tmp_path, '"kinematic-splitting"', None, "solver.max_displacement=1e-3")
    assert code == 1
    assert summary["reason"].startswith("wall blow-out (outward) at t = ")
    assert "max_displacement" in summary["reason"] and "z = " in summary["reason"]
    assert np.max(np.abs(s["eta_z1"])) <= 1e-3 * 0.5 or len(s["t"]) == summary["steps"]


def test_energy_bound():
    bound = EnergyBound(initial=1.0, margin=0.01)
    bound.check(0.1, {"energy.total": 1.5, "work.inlet": 0.5})  # E = E⁰ + W: a conservative scheme
    bound.check(0.2, {"energy.total": 1.2, "work.inlet": 0.0, "dissipation.x": 0.3})
    with pytest.raises(RunFailed, match=r"energy grew beyond the work put in at t = 0.3 s"):
        bound.check(0.3, {"energy.total": 1.6, "work.inlet": 0.05})  # 1.6 > 1.55 by 0.05 / 1.6 > 1 %
