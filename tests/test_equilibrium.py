"""``[initial] pressure``: the wall's static equilibrium under a fluid at rest at a uniform pressure."""

import numpy as np
import pytest
from runs import CASES, run_case_file

from multilayer.case.casefile import load_case
from multilayer.coupling.build import prepare
from multilayer.plugin.problems import CaseError
from multilayer.plugin.registry import Registry
from multilayer.scene.setup import Setup
from multilayer.wall.equilibrium import lumen_force
from multilayer.wall.stack import LUMEN

TENSION, L = 2.0e5, 6.0  # pulse-membrane's wave-membrane (C1, dyn/cm) and length (cm)


def lumen(nz: int, *sets: str) -> tuple[np.ndarray, np.ndarray]:
    """(z, η) of pulse-membrane's initial wall on the lumen's DOFs."""
    case = load_case(CASES / "pulse-membrane.toml", (f"mesh.nz={nz}", "mesh.nr=2", *sets))
    setup = Setup.build(case, Registry.load())
    return setup.wall.lines[LUMEN].z, setup.eta(setup.initial_state())


def test_a_planar_membrane_takes_its_exact_static_deflection():
    """−C1 η'' = P⁰ − P_e, η = 0 at the ends: η = (P⁰ − P_e) z (L − z) / (2 C1), a P2 function: exact to round-off."""
    z, eta = lumen(6, "initial.pressure=1000.0", "loads.external=300.0")
    exact = 700.0 * z * (L - z) / (2 * TENSION)
    assert np.max(np.abs(eta - exact)) <= 1e-13 * np.max(exact)


def test_a_tubes_membrane_takes_the_pressure_on_its_moved_place():
    """In a tube P⁰ acts on r = R + η: −C1 η'' = P⁰ (1 + η/R), so η = R (cos ω(z − L/2) / cos(ωL/2) − 1) with
    ω² = P⁰/(R C1); P2 converges at ≥ third order at the DOFs (the η-independent load would be off by ~η/R)."""
    P, R = 5.0e3, 0.5
    w = np.sqrt(P / (R * TENSION))
    errors = []
    for nz in (6, 12):
        z, eta = lumen(nz, 'geometry.kind="axisymmetric"', f"initial.pressure={P}", "loads.external=0.0")
        exact = R * (np.cos(w * (z - L / 2)) / np.cos(w * L / 2) - 1.0)
        errors.append(np.max(np.abs(eta - exact)) / np.max(exact))
    assert errors[1] < errors[0] / 7.0 and errors[1] < 1e-5, errors


def test_the_fluid_starts_at_rest_at_the_pressure():
    """The state at t = 0 (a snapshot's, a probe's): p = P⁰ everywhere, u = 0."""
    case = load_case(CASES / "physiological-rcr.toml", ("mesh.nz=12", "mesh.nr=3", "initial.pressure=2000.0"))
    setup = Setup.build(case, Registry.load())
    state = setup.initial_state()
    values = setup.probe_values(setup.probe_rows(case.output.probes), state)
    assert all(abs(values[p] - 2000.0) <= 1e-12 * 2000.0 for p in ("p_z1", "p_z3", "p_z5")), values
    assert not np.any(state.fluid.u)


def test_a_pressure_beyond_what_a_tubes_wall_holds_is_refused_by_name():
    """Once P⁰/(R C1) > (π/L)² the pressure on the moved lumen outweighs the membrane's lowest mode's stiffness
    (an equilibrium past buckling, if any): the iteration diverges and says so."""
    with pytest.raises(ValueError, match="initial.pressure = 1e[+]06 did not settle .* a smaller initial.pressure"):
        lumen(6, 'geometry.kind="axisymmetric"', "initial.pressure=1e6")


@pytest.mark.parametrize("lumen", ["no-slip", "radial"])
def test_a_thick_band_at_the_fluid_of_a_tube_settles(lumen):
    """Under no-slip a thick first layer's lumen keeps its d_z free: the iteration's change stalls at 2e-14 of the
    deflection, the round-off of its solves, and stops there (it used to be taken for a wall giving way): K d = f(η)
    holds to the solves' round-off."""
    case = load_case(CASES / "thick-wall.toml", ('geometry.kind="axisymmetric"', f'coupler.lumen="{lumen}"',
                                                 "initial.pressure=1000.0"))
    setup, _ = prepare(case, Registry.load())
    d = setup.initial_state().wall.d
    force = setup.wall.prolongations[LUMEN] @ lumen_force(setup.wall, 1000.0, setup.wall.restrictions[LUMEN] @ d)
    residual = (setup.stack.stiffness @ d - force)[setup.stack.free]
    assert np.max(np.abs(residual)) <= 1e-11 * np.max(np.abs(force))
    assert 3e-3 < np.max(setup.wall.restrictions[LUMEN] @ d) < 4e-3  # 0.7 % of R


@pytest.mark.parametrize("case, pressure, coupler", [
    ("physiological-rcr", 2000.0, '{model="monolithic",scheme="crank-nicolson"}'),
    ("physiological-rcr", 2000.0, '{model="kinematic-splitting",scheme="crank-nicolson",beta=1}'),
    ("pulse-koiter-thick-axisymmetric", 5000.0, '{model="monolithic",scheme="crank-nicolson"}'),
    ("pulse-koiter-thick-axisymmetric", 5000.0, '{model="kinematic-splitting",scheme="crank-nicolson",beta=1}'),
])
def test_a_run_started_at_equilibrium_under_constant_loads_stays_at_rest(tmp_path, case, pressure, coupler):
    """The fluid at rest at P⁰ = the ends' pressure, the wall deflected under P⁰ − P_e: η and Q do not move
    (a planar four-layer wall and a tube, monolithic and the splitting with β = 1, whose first τ̃ is P⁰'s force)."""
    result, data = run_case_file(
        case, tmp_path / "rest", "mesh.nz=12", "mesh.nr=3", "time.end=0.002", "time.dt=2e-4",
        f"loads.inlet={pressure}", f"loads.outlet={pressure}", "loads.external=100.0", f"initial.pressure={pressure}",
        f"coupler={coupler}")
    eta = np.array([data.series[f"eta_z{k}"] for k in range(1, 6)])
    assert np.min(eta) > 1e-2  # deflected: 0.01-0.02 cm
    assert np.max(np.abs(eta - eta[:, :1])) <= 1e-10 * np.max(eta)
    assert max(np.max(np.abs(data.series[q])) for q in ("q_in", "q_out")) <= 1e-8


@pytest.mark.parametrize("case, sets, words", [
    ("pulse-membrane", ("initial.pressure='high'",), "initial.pressure = 'high'"),
    ("pulse-membrane", ("initial.pressure=nan",), "initial.pressure = nan: expected a number"),
    ("pulse-membrane", ("initial.pressure=1000.0", 'initial.displacement.r="0.01"'), "leave initial.displacement out"),
    ("pulse-membrane", ("initial.presure=1000.0",), "did you mean 'pressure'"),
    ("membrane-mode", ("initial.pressure=1000.0",), "the case has not both"),     # no fluid
    ("poiseuille-rigid", ("initial.pressure=1000.0",), "the case has not both"),  # no wall
])
def test_a_bad_initial_pressure_is_refused_with_its_key_path(case, sets, words):
    with pytest.raises(CaseError) as info:
        load_case(CASES / f"{case}.toml", sets)
    assert any(words in str(p) for p in info.value.problems), [str(p) for p in info.value.problems]


def test_an_unset_initial_pressure_leaves_the_resolved_case_alone():
    assert set(load_case(CASES / "pulse-membrane.toml").resolved["initial"]) == {"displacement", "velocity"}
