"""A boundary condition from a test-local plugin: a resistance outlet p = R·Q, with no edit in multilayer/.

The condition is this module's (registered by hand, as ``--plugin`` would):
the fluid asks it for p̄ = 0 + R Q̄ at every step and carries R (∫q·n)(∫ū·n)
in its matrix; the couplers pass it through without knowing its kind.  Its
energy comes back as the column ``dissipation.outlet.resistance`` = Δt R Q̄²,
and the ledger closes with it under every coupler.  On a rigid channel in
steady Stokes flow the channel is a linear resistance R_ch = 3μL/R³ (per unit
depth, half-channel 0 < r < R), so Q = P_in/(R_ch + R) exactly: P2/P1 holds
the parabola, so the discrete steady state is exact to round-off.
"""

import sys

import numpy as np
import pytest
from runs import CASES, run_case_file

from multilayer.boundary.contract import BoundaryCondition, EndTraction
from multilayer.case.casefile import load_case
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.problems import CaseError
from multilayer.plugin.records import BoundaryPlugin, Param
from multilayer.plugin.registry import Registry


class Resistance(BoundaryCondition):
    """p = R·Q at an end, Q its outward flux."""

    implicit = True

    def __init__(self, resistance: float):
        self.resistance = resistance

    def traction(self, window, dt, scheme, history) -> EndTraction:
        return EndTraction(0.0, self.resistance)


@hookimpl
def multilayer_boundaries():
    return [BoundaryPlugin(name="test-resistance", factory=Resistance,
                           params=(Param("resistance", "R", "dyn·s/cm⁴", ge=0.0, doc="p = R Q"),),
                           doc="A resistance p = R Q (a test's own plugin).")]


REGISTRY = Registry.load(extra=[sys.modules[__name__]])
TINY = ("geometry.length=2.0", "mesh.nz=8", "mesh.nr=2", "time.end=0.002",
        'output.probes=[{ name = "eta_z1", quantity = "eta", z = 1.0 }, '
        '{ name = "q_out", quantity = "flow_rate", z = 2.0 }]')
#: the characteristic impedance ρ_f c / R of the pulse-koiter channel, c ≈ √(R C0/ρ_f) ≈ 600 cm/s: ~1.2e3
RESISTANCE = 1.2e3
COUPLERS = [
    '"kinematic-splitting"',
    '{model="kinematic-splitting",scheme="crank-nicolson",beta=1.0}',
    '{model="monolithic",scheme="backward-euler"}',
    '{model="monolithic",scheme="crank-nicolson"}',
    '{model="monolithic",scheme="bdf2"}',
    '{model="dirichlet-neumann-implicit",tolerance=1e-11}',
    '{model="dirichlet-neumann-explicit"}',
]


def run(tmp_path, case, *sets):
    return run_case_file(case, tmp_path, *sets, registry=REGISTRY)


@pytest.mark.parametrize("coupler", COUPLERS)
def test_a_resistance_outlet_under_every_coupler_closes_the_ledger(tmp_path, coupler):
    # explicit DN is stable on a heavy wall, and its volume lags a step (the fluid takes the wall's old velocity)
    heavy = ("layers[0].density=50.0", "solver.volume_margin=2") if "explicit" in coupler else ()
    outlet = f'loads.outlet={{model="test-resistance",resistance={RESISTANCE}}}'
    result, data = run(tmp_path / "r", "pulse-koiter", *TINY, *heavy, outlet, f"coupler={coupler}")
    assert result.status == "ok", result.reason
    s = data.series
    assert np.all(s["energy.relative_residual"] <= 1e-9)
    # the resistance's own column: Δt R Q̄², and the flow does leave through the outlet
    assert np.all(s["dissipation.outlet.resistance"] >= 0.0) and np.max(s["dissipation.outlet.resistance"]) > 0.0
    assert np.all(s["work.outlet"] == 0.0)
    assert data.summary["plugins"]["loads.outlet"]["name"] == "test-resistance"
    # the same scene with p_out = 0: the outlet is no longer free, so the flow out differs
    _, free = run(tmp_path / "free", "pulse-koiter", *TINY, *heavy, f"coupler={coupler}")
    assert np.max(np.abs(s["q_out"] - free.series["q_out"])) > 1e-3 * np.max(np.abs(free.series["q_out"]))


@pytest.mark.parametrize("resistance", [0.0, 5.04, 50.0])
def test_steady_flow_through_a_resistance_outlet_is_exact(tmp_path, resistance):
    # Δt = 1000 s: backward Euler damps the slowest transient (λ₁ = 0.345/s) by 1/(1 + λ₁Δt) ≈ 3e-3 a step
    result, data = run(tmp_path, "poiseuille-rigid", "time.dt=1000.0", "time.end=8000.0",
                       f'loads.outlet={{model="test-resistance",resistance={resistance}}}')
    assert result.status == "ok"
    L, R, mu, p_in = 6.0, 0.5, 0.035, 10.0
    channel = 3.0 * mu * L / R**3  # 5.04
    q = p_in / (channel + resistance)
    s = data.series
    for probe in ("q_in", "q_out"):
        assert s[probe][-1] == pytest.approx(q, rel=1e-11), (probe, s[probe][-1], q)
    # the pressure at the outlet is R Q: the midpoint sits halfway between P_in and R Q
    assert s["p_mid"][-1] == pytest.approx(0.5 * (p_in + resistance * q), rel=1e-10)
    assert np.all(s["energy.relative_residual"] <= 1e-11)


def test_a_bad_resistance_is_a_clear_error_at_its_key_path():
    with pytest.raises(CaseError, match=r"loads.outlet.resistance = -1.0: expected a number >= 0.0"):
        load_case(CASES / "poiseuille-rigid.toml", ['loads.outlet={model="test-resistance",resistance=-1.0}'], REGISTRY)
    with pytest.raises(CaseError, match=r"loads.outlet.model = 'test-resistanse': no such boundary condition; "
                                        r"did you mean 'test-resistance'"):
        load_case(CASES / "poiseuille-rigid.toml", ['loads.outlet={model="test-resistanse",resistance=1.0}'], REGISTRY)
