"""``[initial] pressure``: the wall's static equilibrium under a fluid at rest at a uniform pressure, and the
validation that weighs it against the channel before a run starts."""

import re

import numpy as np
import pytest
from runs import CASES, run_case_file

import multilayer as ml
from multilayer.case.casefile import load_case
from multilayer.case.trial_walls import SMALL_DEFLECTION
from multilayer.commands.main import main
from multilayer.coupling.build import prepare
from multilayer.plugin.problems import CaseError
from multilayer.plugin.registry import Registry
from multilayer.scene.setup import Setup
from multilayer.wall.equilibrium import Unsettled, lumen_force, static_deflection
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
    ω² = P⁰/(R C1); P2 converges at ≥ third order at the DOFs (the η-independent load would be off by ~η/R;
    here η/R = 0.21 at the middle, under the bound validation sets)."""
    P, R = 4.0e3, 0.5
    w = np.sqrt(P / (R * TENSION))
    errors = []
    for nz in (6, 12):
        z, eta = lumen(nz, 'geometry.model="axisymmetric"', f"initial.pressure={P}", "loads.external=0.0")
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


def test_a_pressure_beyond_what_a_tubes_wall_holds_does_not_settle_and_says_so():
    """Once P⁰/(R C1) > (π/L)² the pressure on the moved lumen outweighs the membrane's lowest mode's stiffness
    (an equilibrium past buckling, if any): the iteration diverges and says so, keeping its first iterate, the
    deflection under the load on the reference lumen: P⁰ z (L − z)/(2 C1), a P2 function, exact."""
    case = load_case(CASES / "pulse-membrane.toml", ("mesh.nz=6", "mesh.nr=2", 'geometry.model="axisymmetric"'))
    setup = Setup.build(case, Registry.load())
    with pytest.raises(Unsettled, match="initial.pressure = 1e[+]06 did not settle .* a smaller initial.pressure") as info:
        static_deflection(setup.stack, 1.0e6, 0.0)
    z, linear = setup.wall.lines[LUMEN].z, setup.wall.restrictions[LUMEN] @ info.value.linear
    assert np.max(np.abs(linear - 1.0e6 * z * (L - z) / (2 * TENSION))) <= 1e-13 * 22.5


@pytest.mark.parametrize("lumen", ["no-slip", "radial"])
def test_a_thick_band_at_the_fluid_of_a_tube_settles(lumen):
    """Under no-slip a thick first layer's lumen keeps its d_z free: the iteration's change stalls at 2e-14 of the
    deflection, the round-off of its solves, and stops there (it used to be taken for a wall giving way): K d = f(η)
    holds to the solves' round-off."""
    case = load_case(CASES / "thick-wall.toml", ('geometry.model="axisymmetric"', f'coupler.lumen="{lumen}"',
                                                 "initial.pressure=1000.0"))
    setup, _ = prepare(case, Registry.load())
    d = setup.initial_state().wall.d
    force = setup.wall.prolongations[LUMEN] @ lumen_force(setup.wall, 1000.0, setup.wall.restrictions[LUMEN] @ d)
    residual = (setup.stack.stiffness @ d - force)[setup.stack.free]
    assert np.max(np.abs(residual)) <= 1e-11 * np.max(np.abs(force))
    assert 3e-3 < np.max(setup.wall.restrictions[LUMEN] @ d) < 4e-3  # 0.7 % of R


def test_the_bound_on_the_static_deflection_is_a_quarter_of_the_radius():
    """The planar membrane's exact η = P⁰ z (L − z)/(2 C1) peaks at P⁰ L²/(8 C1) = 2.25e-5 P⁰ cm: R/4 = 0.125 cm at
    P⁰ = 5555.6; 5500 validates, 5600 is refused with its deflection, exact, at z = L/2."""
    assert SMALL_DEFLECTION == 0.25
    load_case(CASES / "pulse-membrane.toml", ["initial.pressure=5500.0"])
    with pytest.raises(CaseError) as info:
        load_case(CASES / "pulse-membrane.toml", ["initial.pressure=5600.0"])
    assert [str(p) for p in info.value.problems] == [
        "initial.pressure = 5600.0: the wall's static equilibrium under it moves the lumen by η = 0.126 cm at z = 3 cm, "
        "0.252 R (R = 0.5 cm); expected |η| ≤ 0.25 R = 0.125 cm (the linear wall's small strain); a smaller "
        "initial.pressure or a stiffer wall (from --set)"]


#: what the run's wall would be at t = 0 in the message, and what the user should check beyond it
UNITS = "check that the layers' moduli and initial.pressure are in dyn/cm² (1 kPa = 1e4 dyn/cm², 1 mmHg = 1333.2"


@pytest.mark.parametrize("case, sets, words", [
    # the media's modulus in kPa (400) instead of dyn/cm² (4e6): no equilibrium
    ("carotid", ("layers[1].young=400",),
     ("initial.pressure = 100000.0: the wall cannot hold it: under it the linear wall alone moves the lumen by η = "
      "0.655204 cm at z = 5.9 cm, 2.18 R (R = 0.3 cm), and the pressure on the moved lumen outgrows its stiffness",
      "expected |η| ≤ 0.25 R = 0.075 cm", UNITS)),
    # every modulus in Pa read as dyn/cm²: ten times too soft
    ("carotid", ("layers[0].young=2e5", "layers[1].young=4e5", "layers[2].young=2e5"),
     ("the wall cannot hold it", "η = 0.345247 cm at z = 0.7 cm, 1.15 R", UNITS)),
    ("carotid", ("initial.pressure=1e9",), ("initial.pressure = 1000000000.0: the wall cannot hold it", UNITS)),
    # 150 mmHg: an equilibrium, but beyond the linear wall's small strain
    ("carotid", ("initial.pressure=2e5",),
     ("initial.pressure = 200000.0: the wall's static equilibrium under it moves the lumen by η = 0.0895604 cm at "
      "z = 0.7 cm, 0.299 R (R = 0.3 cm); expected |η| ≤ 0.25 R = 0.075 cm (the linear wall's small strain); a "
      "smaller initial.pressure or a stiffer wall (from --set)",)),
    # an outer pressure that crushes the tube
    ("physiological-flow", ("loads.external=1e5",),
     ("initial.pressure = 2666.4: the wall's static equilibrium under it and loads.external = 100000 at t = 0 moves "
      "the lumen by η = -1.23637 cm at z = 3 cm, 2.47 R (R = 0.5 cm) (R + η ≤ 0: the lumen closes)", UNITS)),
    # a tighter limit of the run's own
    ("carotid", ("solver.max_displacement=0.1",),
     ("η = 0.0389953 cm at z = 0.7 cm, 0.13 R (R = 0.3 cm); expected |η| ≤ 0.1 R = 0.03 cm ([solver] "
      "max_displacement: the run would stop at once); a smaller initial.pressure, a stiffer wall or a larger "
      "solver.max_displacement",)),
    # a wall without stiffness
    ("pulse-membrane", ("layers[0].tension=0.0", "initial.pressure=1000.0"),
     ("initial.pressure = 1000.0: the wall has no static equilibrium under it: its stiffness is singular",)),
])
def test_a_static_start_the_wall_cannot_hold_is_refused_at_validation(case, sets, words):
    """One problem at initial.pressure, with the deflection the run would start from, in cm and in R."""
    with pytest.raises(CaseError) as info:
        load_case(CASES / f"{case}.toml", sets)
    found = [str(p) for p in info.value.problems]
    assert len(found) == 1 and all(w in found[0] for w in words), found


@pytest.mark.parametrize("case, sets", [
    ("carotid", ()),                                                         # thin first layer, splitting
    ("carotid", ('coupler={model="monolithic",scheme="bdf2"}',)),
    ("thick-wall", ('geometry.model="axisymmetric"', 'coupler.lumen="no-slip"', "initial.pressure=1000.0")),
    ("thick-wall", ('geometry.model="axisymmetric"', 'coupler.lumen="radial"', "initial.pressure=1000.0")),
    ("physiological-flow", ("loads.external=300.0",)),
])
def test_validation_weighs_the_deflection_the_run_starts_from(case, sets):
    """The validator's wall is the run's (its coupler's radial lines, a fluid's pinned lumen ends: no-slip and
    radial differ by 4 % here): under a bound of 1e-9 R it reports the run's own largest |η| at t = 0."""
    registry = Registry.load()
    setup, _ = prepare(load_case(CASES / f"{case}.toml", sets, registry), registry)
    eta = setup.eta(setup.initial_state())
    with pytest.raises(CaseError) as info:
        load_case(CASES / f"{case}.toml", (*sets, "solver.max_displacement=1e-9"), registry)
    found = re.search(r"moves the lumen by η = (\S+) cm", str(info.value))
    assert found and float(found[1]) == float(f"{eta[np.argmax(np.abs(eta))]:.6g}"), str(info.value)


def test_the_cli_and_the_api_refuse_it_before_anything_runs(tmp_path, capsys):
    """``validate`` and ``run``: exit 2, the file and one line on stderr, no traceback, no results folder;
    ``ml.load_case``: the same CaseError."""
    case, sets = str(CASES / "carotid.toml"), ["--set", "layers[1].young=400"]
    for argv in (["validate", case, *sets], ["run", case, "--out", str(tmp_path / "out"), *sets]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 2 and err[0].endswith("carotid.toml: invalid case"), err
        assert err[1].startswith("initial.pressure = 100000.0: the wall cannot hold it") and "Traceback" not in err[1]
    assert not (tmp_path / "out").exists()
    with pytest.raises(CaseError, match="initial.pressure = 100000.0: the wall cannot hold it"):
        ml.load_case(case, {"layers[1].young": 400})


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
