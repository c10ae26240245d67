"""The kinematic splitting under the wall's impedance (``robin = "impedance"``, theory §6): the condensed wall
step, the wall that moves with the fluid, the volume it keeps, and the paper's Robin term it replaces."""

import numpy as np
import pytest

from multilayer.case.casefile import load_case
from multilayer.commands.main import main
from multilayer.coupling.build import prepare
from multilayer.coupling.structure import StructureStep
from multilayer.numerics.linsolve import SolverStats
from multilayer.plugin.registry import Registry
from multilayer.runner.stepping import Tally, iterate_steps
from multilayer.wall.stack import LUMEN
from multilayer_plugins.kinematic_splitting import interface_impedance
from tests.runs import CASES, run_cli

COARSE = ("mesh.nz=12", "mesh.nr=3", "time.dt=1e-4", "time.end=0.002")


@pytest.fixture(scope="module")
def thick_setup():
    case = load_case(CASES / "pulse-koiter-thick.toml", COARSE)
    setup, coupler = prepare(case, Registry.load())
    return setup, coupler


@pytest.mark.parametrize("scheme", ["backward-euler", "crank-nicolson"])
def test_the_impedance_inverts_the_wall_steps_response_on_the_lumen(thick_setup, scheme):
    """S_Γ G = I on the free line DOFs, and a load τ on Γ moves the wall's V̄ by exactly A⁻¹Pτ (linearity)."""
    from multilayer.numerics.timescheme import named

    setup, coupler = thick_setup
    S = named(scheme)
    step = StructureStep(setup.stack, S, 1e-4, SolverStats(), fluid_line=LUMEN)
    P, R = setup.wall.prolongations[LUMEN], setup.wall.restrictions[LUMEN]
    impedance, response = interface_impedance(step, P, R, 1e-4)
    G = R @ response
    free = np.flatnonzero(np.diag(G) > 0)
    assert free.size == P.shape[1] - 2  # the lumen's two clamped ends
    assert np.allclose((impedance @ G)[np.ix_(free, free)], np.eye(free.size), rtol=0, atol=1e-10)
    state = coupler.initial_state(setup)
    tau = np.random.default_rng(0).normal(size=P.shape[1])
    free_step = step.step(state, {})
    loaded = step.step(state, {"fluid": P @ tau})
    change = loaded.mean - free_step.mean
    assert np.max(np.abs(change - response @ tau)) <= 1e-12 * np.max(np.abs(change))


def test_the_wall_moves_with_the_fluid_at_every_level():
    """After every step the band's velocity on Γ is the thin layer's and the fluid's trace (v̄ = V̄_Γ, both
    levels of Crank–Nicolson): the kinematic condition holds for the whole wall, not for the thin layer alone."""
    case = load_case(CASES / "pulse-koiter-thick.toml",
                     (*COARSE, 'coupler={model="kinematic-splitting",scheme="crank-nicolson"}'))
    setup, coupler = prepare(case, Registry.load())
    state = coupler.initial_state(setup)
    tally = Tally.start(setup, coupler, state)
    R = setup.wall.restrictions[LUMEN]
    gaps = []
    for step in iterate_steps(setup, coupler, state, tally, setup.probe_rows(case.output.probes)):
        s = step.state
        gaps.append(np.max(np.abs(R @ s.wall.V - s.v)) / max(np.max(np.abs(s.v)), 1e-300))
    assert len(gaps) == 20 and max(gaps) <= 1e-10


@pytest.mark.parametrize("robin, tolerance", [("impedance", 1e-9), ("inertia", None)])
def test_the_volume_follows_the_flow_under_the_impedance(tmp_path, robin, tolerance):
    """The same coarse pulse, Crank–Nicolson β = 1: the impedance keeps the planar volume balance to round-off;
    the paper's Robin term drifts by a large share of the volume moved (theory §7, "Volume")."""
    code, summary, _ = run_cli("pulse-koiter-thick", tmp_path / robin, *COARSE, "solver.volume_margin=1e9",
                               f'coupler={{model="kinematic-splitting",scheme="crank-nicolson",beta=1,robin="{robin}"}}')
    assert code == 0 and summary["status"] == "ok"
    volume = summary["volume"]
    if tolerance is not None:
        assert volume["max_relative_residual"] <= tolerance
    else:  # measured: a step whose whole inflow leaves through Γ (relative residual 2.0), drift 7.6 % of the moved
        assert volume["max_relative_residual"] > 1.0 and volume["relative_drift"] > 0.05, volume


def test_the_papers_robin_term_refuses_a_flow_rate_inlet(capsys):
    code = main(["validate", str(CASES / "physiological-flow.toml"),
                 "--set", 'coupler={model="kinematic-splitting",robin="inertia"}'])
    err = capsys.readouterr().err
    assert code == 2
    assert "loads.inlet prescribes a flow rate" in err and "robin" in err and "impedance" in err
