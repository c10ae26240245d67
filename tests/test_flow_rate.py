"""The ``flow-rate`` end: a prescribed inflow Q(t), its mean pressure a Lagrange multiplier λ.

A rigid channel in steady Stokes flow is a linear resistance R_ch = 3μL/R³
(per unit depth, half channel 0 < r < R): a prescribed Q needs the pressure
drop λ = R_ch Q, and P2/P1 holds the parabola, so the discrete steady state
is exact to round-off.  On the coupled pulse scene the multiplier and its
constraint are one more row and column of the fluid's system, which every
coupler takes as it is; the ledger closes with the prescribed flow's work
Δt λ Q̄_in (column ``work.inlet``).  Womersley flow driven by a prescribed
Q(t): tests/test_fluid_womersley.py.
"""

import attrs
import numpy as np
import pytest
from runs import CASES, assert_resume_is_bit_identical, run_case_file
from test_boundary_plugins import TINY

from multilayer.case.casefile import load_case
from multilayer.commands.main import main
from multilayer.coupling.build import prepare
from multilayer.plugin.problems import CaseError
from multilayer.plugin.registry import Registry

REGISTRY = Registry.load()
L, R, MU = 6.0, 0.5, 0.035  # cases/poiseuille-rigid.toml
#: the inflow pulse of the coupled scene: cm²/s per unit depth, about what the pressure pulse of pulse-koiter drives
PULSE = '{model="cosine-pulse",amplitude=20.0,duration=0.003}'
COUPLERS = [
    '"kinematic-splitting"',
    '{model="kinematic-splitting",scheme="crank-nicolson",beta=1.0}',
    '{model="kinematic-splitting",beta=1.0}',
    '{model="kinematic-splitting",scheme="crank-nicolson"}',
    '{model="monolithic",scheme="backward-euler"}',
    '{model="monolithic",scheme="crank-nicolson"}',
    '{model="monolithic",scheme="bdf2"}',
    '{model="dirichlet-neumann-implicit",tolerance=1e-11}',
]


def run(tmp_path, case, *sets):
    return run_case_file(case, tmp_path, *sets, registry=REGISTRY)


def test_a_prescribed_flow_through_a_rigid_channel_is_poiseuille_to_round_off(tmp_path):
    # Δt = 1000 s: backward Euler damps the slowest transient (λ₁ = 0.345/s) by 1/(1 + λ₁Δt) ≈ 3e-3 a step
    q = 1.5
    sections = ", ".join(f'{{ name = "q{i}", quantity = "flow_rate", z = {z} }}' for i, z in enumerate((0, 1.5, 3, 6)))
    result, data = run(tmp_path, "poiseuille-rigid", "time.dt=1000.0", "time.end=8000.0",
                       f'loads.inlet={{model="flow-rate",flow={q}}}',
                       f'output.probes=[{sections}, {{ name = "p_mid", quantity = "p", z = 3.0, r = 0.25 }}, '
                       f'{{ name = "uz_axis", quantity = "u_z", z = 3.0, r = 0.0 }}]')
    assert result.status == "ok", result.reason
    s = data.series
    drop = 3.0 * MU * L / R**3 * q  # R_ch Q: 7.56 dyn/cm²
    # measured (relative): λ 3.1e-15, the section fluxes ≤ 3.2e-14 (at the outlet), p_mid 4.8e-15, u_axis 1.3e-15
    assert s["end.inlet.p"][-1] == pytest.approx(drop, rel=1e-13)
    assert s["end.inlet.Q"][-1] == pytest.approx(-q, rel=1e-13)
    for section in ("q0", "q1", "q2", "q3"):
        assert s[section][-1] == pytest.approx(q, rel=1e-12), section
    assert s["p_mid"][-1] == pytest.approx(0.5 * drop, rel=1e-12)
    assert s["uz_axis"][-1] == pytest.approx(1.5 * q / R, rel=1e-12)  # u_max = 3Q/(2R)
    # the prescribed flow's work Δt λ Q̄_in, and the ledger
    assert s["work.inlet"][-1] == pytest.approx(1000.0 * drop * q, rel=1e-12)
    assert np.all(s["energy.relative_residual"] <= 1e-11)
    # the Stokes matrix on a rigid wall, multiplier and all, is factorized once
    assert data.summary["factorizations"]["fluid"] == 1
    assert data.summary["case"]["loads"]["inlet"] == {"model": "flow-rate", "flow": {"model": "constant", "value": q}}


@pytest.mark.parametrize("coupler", COUPLERS)
def test_a_flow_rate_inlet_under_every_coupler_closes_the_ledger(tmp_path, coupler):
    probes = 'output.probes=[{ name = "q_in", quantity = "flow_rate", z = 0.0 }]'
    result, data = run(tmp_path, "pulse-koiter", *TINY, probes, f"loads.inlet={{model=\"flow-rate\",flow={PULSE}}}",
                       f"coupler={coupler}")
    assert result.status == "ok", result.reason
    s = data.series
    # measured ≤ 5.1e-13 under every coupler (the relative residual of the run's ledger)
    assert np.all(s["energy.relative_residual"] <= 1e-9)
    # each new level carries the prescribed inflow Q(tⁿ⁺¹) (the inlet does not move: J = 1), to the solves'
    # accuracy, ‖b − Ax‖ ≤ 1e-12 ‖b‖ with ‖b‖ ≫ Q: measured 2.5e-15 (DN implicit) to 2.8e-11 of the peak
    inflow = 10.0 * (1.0 - np.cos(2.0 * np.pi * s["t"] / 0.003))
    assert np.max(np.abs(s["q_in"] - inflow)) <= 1e-9 * np.max(inflow)
    # the prescribed flow's work is Δt λ Q̄_in, with λ the inlet's mean pressure (column end.inlet.p)
    assert s["work.inlet"] == pytest.approx(-1e-4 * s["end.inlet.p"] * s["end.inlet.Q"], rel=1e-12)
    assert np.max(s["end.inlet.p"]) > 1e3  # the pressure it takes to push the pulse in: a few thousand dyn/cm²


def test_monolithic_and_dirichlet_neumann_find_the_same_multiplier(tmp_path):
    """The multiplier is a property of the coupled step, not of the coupler that solves it (both backward Euler)."""
    inlet = f'loads.inlet={{model="flow-rate",flow={PULSE}}}'
    _, mono = run(tmp_path / "m", "pulse-koiter", *TINY, inlet, 'coupler={model="monolithic"}')
    _, dn = run(tmp_path / "d", "pulse-koiter", *TINY, inlet, 'coupler={model="dirichlet-neumann-implicit",'
                                                              'tolerance=1e-11}')
    # measured: 1.5e-11 of the largest λ apart (the interface iteration's tolerance, 1e-11)
    lam = mono.series["end.inlet.p"]
    assert np.max(np.abs(dn.series["end.inlet.p"] - lam)) <= 1e-8 * np.max(np.abs(lam))


def test_a_flow_given_as_a_table_or_a_formula(tmp_path):
    table = tmp_path / "q.csv"
    table.write_text("t, q\n0, 0\n0.001, 1.0\n0.01, 1.0\n")
    case = tmp_path / "case.toml"
    case.write_text((CASES / "poiseuille-rigid.toml").read_text())
    for flow in ('{model="table",file="q.csv"}', '"minimum(1e3*t, 1)"'):
        loaded = load_case(case, [f'loads.inlet={{model="flow-rate",flow={flow}}}', "time.end=0.004",
                                  "time.dt=0.001"], REGISTRY)
        q = loaded.loads.inlet.flow
        assert [float(q.value(t)) for t in (0.0, 0.0005, 0.002)] == pytest.approx([0.0, 0.5, 1.0], rel=1e-14)


@pytest.mark.parametrize("inlet, message", [
    ('{model="flow-rate"}', r"loads.inlet.flow: missing; expected a number, a formula in t or a table \{model = ...\} "
                           r"\(cm²/s per unit depth \(planar\), cm³/s \(tube\)\)"),
    ('{model="flow-rate",flow={model="sine",amplitude="2",frequency=1.0}}',
     r"loads.inlet.flow.amplitude = '2': expected a number \(cm²/s per unit depth"),
    ('{model="flow-rate",flow={model="sine",amplitude=2.0,frequency=-1.0}}',
     r"loads.inlet.flow.frequency = -1.0: expected a number > 0.0 \(Hz\)"),
    ('{model="flow-rate",flow={model="sinus",amplitude=2.0}}',
     r"loads.inlet.flow.model = 'sinus': no such flow rate load; did you mean 'sine'"),
    ('{model="flow-rate",flow="2*sin(2*pi*s)"}', r"loads.inlet.flow = '2\*sin\(2\*pi\*s\)': invalid formula in t"),
    ('{model="flow-rate",flow={model="table",file="nowhere.csv"}}', r"loads.inlet.flow.file = 'nowhere.csv': no such file"),
    ('{model="flow-rate",flow=[1.0]}', r"loads.inlet.flow = \[1.0\]: expected a number, a formula in t or a table"),
    ('{model="flow-rate",flow=2.0,pressure=1.0}', r"loads.inlet.pressure = 1.0: unknown key"),
])
def test_bad_input_is_a_clear_error_at_its_key_path(inlet, message):
    with pytest.raises(CaseError, match=message):
        load_case(CASES / "poiseuille-rigid.toml", [f"loads.inlet={inlet}"], REGISTRY)


BOTH = ('loads.inlet={model="flow-rate",flow=1.0}', 'loads.outlet={model="flow-rate",flow=-1.0}')


#: what a given motion of the wall ties the two flow rates to
GIVEN = ("whose every step {} gives the wall's motion: the volume between them changes only as that motion does, so "
         "the two flow rates must add up to its change at every step")


@pytest.mark.parametrize("case, sets, wall", [
    ("poiseuille-rigid", (), "in a rigid wall ('fluid-only'): the volume between them is fixed, so what flows in at "
                             "one end must flow out at the other at every step"),
    ("prescribed-wall", (), GIVEN.format("'fluid-only'")),
    ("carotid", ('coupler="dirichlet-neumann-implicit"',), GIVEN.format("'dirichlet-neumann-implicit'")),
])
def test_a_flow_rate_at_both_ends_of_a_fluid_that_moves_no_wall_is_refused_at_validation(case, sets, wall):
    """A rigid wall, a prescribed one, or a coupler whose fluid step is given the wall's motion: the two rates are
    tied to a given volume and no end sets the pressure's level.  One problem, naming both ends."""
    with pytest.raises(CaseError) as info:
        load_case(CASES / f"{case}.toml", (*sets, *BOTH), REGISTRY)
    assert [str(p) for p in info.value.problems] == [
        f"loads.outlet.model = 'flow-rate': a flow rate at both ends (loads.inlet.model = 'flow-rate' too) of a fluid "
        f"{wall}, and no end sets the level of the pressure; expected a flow rate at one end at most; give the other "
        f"end a pressure, a resistance or a windkessel, or couple a compliant wall ([[layers]] with 'monolithic' or "
        f"'kinematic-splitting'), which stores the difference (from --set)"]


def test_the_cli_refuses_it_in_one_line_before_anything_runs(tmp_path, capsys):
    sets = [a for s in BOTH for a in ("--set", s)]
    for argv in (["validate", str(CASES / "poiseuille-rigid.toml"), *sets],
                 ["run", str(CASES / "poiseuille-rigid.toml"), "--out", str(tmp_path / "out"), *sets]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 2 and err[1].startswith("loads.outlet.model = 'flow-rate': a flow rate at both ends"), err
    assert not (tmp_path / "out").exists()


def test_the_fluid_refuses_it_too_when_built_without_validation():
    """The fluid's own guard, for a setup built from a case assembled in Python."""
    case = load_case(CASES / "poiseuille-rigid.toml", BOTH[:1], REGISTRY)
    case = attrs.evolve(case, loads=attrs.evolve(case.loads, outlet=case.loads.inlet))
    with pytest.raises(ValueError, match="a flow rate at both ends of a fluid on a rigid wall"):
        prepare(case, REGISTRY)


def test_a_compliant_wall_stores_what_two_flow_rates_leave_behind(tmp_path):
    """A closed outlet (flow 0) on the planar quick start under monolithic: the inflow has nowhere to go but the
    wall, which takes it; the volume ledger closes to round-off (a planar wall moving with the fluid's velocity)
    and the lumen holds what came in."""
    result, data = run(tmp_path, "quick-start", "mesh.nz=20", "mesh.nr=3", "time.end=0.002",
                       f"loads.inlet={{model=\"flow-rate\",flow={PULSE}}}", 'loads.outlet={model="flow-rate",flow=0.0}')
    assert result.status == "ok", result.reason
    s = data.series
    assert np.max(np.abs(s["volume.relative_residual"])) <= 1e-10
    assert np.max(np.abs(s["end.outlet.Q"])) <= 1e-12 * np.max(np.abs(s["end.inlet.Q"]))
    moved = s["volume.fluid"][-1] - 6.0 * 0.5  # from the channel at rest, L × R (cm² per unit depth)
    assert moved > 0.02 and abs(moved - float(np.sum(-s["end.inlet.Q"] * 1e-4))) <= 1e-12 * moved  # Δt = 1e-4


def test_a_run_with_a_flow_rate_inlet_resumes_bit_identical(tmp_path):
    """λ is the flow-rate end's state: a run resumed from its checkpoint writes the same bytes as one that ran
    through (with the same checkpoints)."""
    assert_resume_is_bit_identical(tmp_path, "pulse-koiter", *TINY, f"loads.inlet={{model=\"flow-rate\",flow={PULSE}}}")


@pytest.mark.parametrize("coupler, words", [
    ('"dirichlet-neumann-explicit"', "incompressibility dilemma"),
    ('{model="kinematic-splitting",robin="inertia"}', "robin = 'inertia'"),
])
def test_a_coupler_that_cannot_keep_a_prescribed_inflow_refuses_it_up_front(coupler, words):
    """The carotid-like scene (issue 35): explicit Dirichlet–Neumann blew up at its first step, the paper's
    splitting lost half the inflow through the wall; both are refused at validation, saying why and what to use."""
    with pytest.raises(CaseError) as info:
        load_case(CASES / "carotid.toml", [f"coupler={coupler}"])
    found = [str(p) for p in info.value.problems]
    assert any("loads.inlet prescribes a flow rate" in p and words in p for p in found), found
