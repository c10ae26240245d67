"""Adaptive keys of ``[time]`` (tolerance, dt_min, dt_max, output_interval, memory, control, size): read, bounded,
refused with key paths."""

import pytest
from runs import CASES

from multilayer.case.casefile import load_case
from multilayer.plugin.problems import CaseError

CN_SPLIT = 'coupler={model="kinematic-splitting",scheme="crank-nicolson",beta=1}'


def problems(*sets: str) -> list[str]:
    with pytest.raises(CaseError) as info:
        load_case(CASES / "pulse-koiter-thick.toml", sets)
    return [str(p) for p in info.value.problems]


@pytest.mark.parametrize("sets, path, words", [
    (("time.tolerance=0",), "time.tolerance", "> 0.0"),
    (("time.tolerance=-1e-3",), "time.tolerance", "> 0.0"),
    (("time.tolerance=1e-3", "time.dt_min=1e-3", "time.dt_max=1e-4"), "time.dt_min", "at most time.dt_max"),
    (("time.tolerance=1e-3", "time.dt_min=1e-3"), "time.dt", "at least time.dt_min"),
    (("time.tolerance=1e-3", "time.dt_max=1e-5"), "time.dt", "at most time.dt_max"),
    (("time.dt_min=1e-5",), "time.dt_min", "read only with adaptive steps"),
    (("time.output_interval=1e-3",), "time.output_interval", "read only with adaptive steps"),
    (("time.tolerance=1e-3", "time.dt_min=1e-12"), "time.dt_min", "expected at most"),
    (("time.tolerance=1e-3", "time.memory=0"), "time.memory", "> 0.0"),
    (("time.tolerance=1e-3", "time.memory=-0.02"), "time.memory", "> 0.0"),
    (("time.memory=0.02",), "time.memory", "read only with adaptive steps"),
    (("time.tolerance=1e-3", "time.output_interval=1e-300"), "time.output_interval", "at least the smallest step"),
    (("time.tolerance=1e-3", 'time.control="per_step"'), "time.control", "per-step"),
    (('time.control="per-step"',), "time.control", "read only with adaptive steps"),
    (("time.tolerance=1e-3", 'time.size="period"'), "time.size", "so-far"),
    (('time.size="memory"',), "time.size", "read only with adaptive steps"),
])
def test_bad_adaptive_time_keys_are_refused_with_their_key_path(sets, path, words):
    found = problems(CN_SPLIT, *sets)
    assert any(p.startswith(path) and words in p for p in found), found


@pytest.mark.parametrize("coupler", ['{model="kinematic-splitting"}', '{model="monolithic",scheme="backward-euler"}',
                                     '{model="fluid-only",scheme="bdf2"}',
                                     '{model="dirichlet-neumann-implicit"}'])
def test_a_coupler_without_an_error_estimate_refuses_a_tolerance(coupler):
    found = problems(f"coupler={coupler}", "time.tolerance=1e-3")
    assert any("time.tolerance = 0.001 asks for adaptive steps" in p for p in found), found


def test_unset_adaptive_keys_leave_the_resolved_case_and_its_hash_alone():
    case = load_case(CASES / "pulse-koiter-thick.toml")
    assert set(case.resolved["time"]) == {"end", "dt"} and not case.time.adaptive


def test_validate_describes_adaptive_steps(capsys):
    """``multilayer validate`` names the tolerance, the control, the first step and the bounds, not a count of
    steps of the first step."""
    from multilayer.commands.main import main
    code = main(["validate", str(CASES / "physiological-flow.toml"), "--set", "time.dt=1e-4", "--set",
                 "time.tolerance=1e-3", "--set", 'time.control="per-step"', "--set", "time.dt_max=8e-3"])
    out = capsys.readouterr().out
    assert code == 0
    assert "adaptive steps to 3 s: tolerance 0.001 (per-step), first step 0.0001 s, at most 0.008 s" in out
    assert "steps of" not in out


def test_a_study_compares_runs_that_differ_from_the_reference_in_any_adaptive_key():
    """``study --vary time.control=...`` (or any key only adaptive steps read) is compared with the fixed-Δt
    reference, as ``time.tolerance`` is: the keys come from the schema, so a new one cannot be left out."""
    from multilayer.campaign.study import FREE_KEYS, case_differences
    from multilayer.case.schema import ADAPTIVE_KEYS
    reference = {"time": {"end": 1.0, "dt": 1e-4}}
    for key in ("tolerance", *ADAPTIVE_KEYS):
        run = {"time": {"end": 1.0, "dt": 1e-3, key: "per-step" if key == "control" else 1e-3}}
        assert case_differences(reference, run, FREE_KEYS) == [], key
