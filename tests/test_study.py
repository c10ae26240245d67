"""``multilayer study``: the measurements on data with known answers, bad input, one small study end to end."""

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from multilayer.campaign import accuracy, planning, study
from multilayer.campaign.variants import Variant
from multilayer.commands.main import main
from multilayer.results.reading import read_run

CASES = Path(__file__).parents[1] / "cases"
PULSE = CASES / "pulse-koiter.toml"
MEMBRANE = CASES / "membrane-mode.toml"


# -- the measurements on synthetic data -------------------------------------------


@pytest.mark.parametrize("p", [1, 2])
def test_exact_error_sequences_give_their_order(p):
    dt = [1e-3, 5e-4, 2e-4, 1e-4, 2.5e-5]  # ratios 2, 2.5, 2, 4
    errors = [0.7 * h**p for h in dt]
    orders = accuracy.observed_orders(dt, errors)
    assert len(orders) == 4
    for order in orders:
        assert order == pytest.approx(p, abs=1e-12)


def test_orders_skip_missing_or_zero_errors_and_need_decreasing_steps():
    assert accuracy.observed_orders([4.0, 2.0, 1.0, 0.5], [4.0, None, 1.0, 0.0]) == [None, None, None]
    with pytest.raises(ValueError, match="decrease"):
        accuracy.observed_orders([1.0, 2.0], [1.0, 2.0])


def test_pareto_front_of_a_hand_made_set():
    #        a     b     c     d     e     f     g
    cost = [1.0, 2.0, 2.0, 3.0, 4.0, 5.0, 5.0]
    error = [0.5, 0.2, 0.3, 0.2, 0.05, 0.05, 0.01]
    # c: b is as cheap and more accurate; d: b cheaper, same error; f: e cheaper, same error
    assert accuracy.pareto_front(cost, error) == [0, 1, 4, 6]
    assert accuracy.pareto_front([1.0, 1.0], [0.1, 0.1]) == [0, 1]  # equal points do not beat each other
    assert accuracy.pareto_front([], []) == []


@pytest.mark.parametrize("p", [1.0, 2.0, 1.5])
@pytest.mark.parametrize("dt", [[4e-4, 2e-4, 1e-4], [5e-4, 2e-4, 1e-4]])
def test_richardson_recovers_order_and_error_of_a_manufactured_sequence(p, dt):
    exact, c = 0.3, 40.0
    x = [exact + c * h**p for h in dt]  # X(Δt) = X + C Δt^p
    order = accuracy.richardson_order(dt, abs(x[0] - x[1]), abs(x[1] - x[2]))
    assert order == pytest.approx(p, abs=1e-10)
    estimate = accuracy.richardson(abs(x[1] - x[2]), dt[1] / dt[2], order)
    assert estimate == pytest.approx(abs(x[2] - exact), rel=1e-9)
    assert accuracy.richardson_order(dt, 0.0, 1.0) is None


def test_cost_to_target_measured_estimated_not_reached():
    wall, error = [1.0, 3.0, 2.0, 8.0], [0.3, 0.04, 0.045, 0.02]
    # two runs meet 5 %: the cheaper one, not the finer
    assert accuracy.cost_to_target(wall, error, 0.05) == {"how": "measured", "wall_time_s": 2.0, "run": 2, "order": None}
    # none meets 1 %: from the finest run, t ∝ 1/Δt and e ∝ Δt^p → t = 8·(0.02/0.01)^(1/p)
    estimated = accuracy.cost_to_target(wall, error, 0.01, finest=3, order=1.0)
    assert estimated["how"] == "estimated" and estimated["wall_time_s"] == pytest.approx(16.0, rel=1e-15)
    assert accuracy.cost_to_target(wall, error, 0.01, finest=3, order=2.0)["wall_time_s"] == pytest.approx(
        8.0 * math.sqrt(2.0), rel=1e-15)
    for order in (None, 0.0, -1.0):
        assert accuracy.cost_to_target(wall, error, 0.01, finest=3, order=order)["how"] == "not reached"


def test_probe_errors_interpolate_the_reference_and_skip_times_past_its_end():
    t_ref = np.linspace(0.0, 1.0, 1001)
    y_ref = np.sin(2 * np.pi * t_ref)  # max 1 at t = 0.25, a row of both grids
    t = np.concatenate([np.linspace(0.0, 1.0, 41), [1.1, 1.2]])  # two rows past the reference's end
    y = np.concatenate([1.1 * np.sin(2 * np.pi * t[:-2]), [50.0, 60.0]])
    e = accuracy.probe_errors(t, y, t_ref, y_ref)
    # |1.1 sin − sin| is largest at the peak: 0.1 of max |sin| = 1
    assert e["relative_linf"] == pytest.approx(0.1, rel=1e-12)
    assert e["peak_error"] == pytest.approx(0.1, rel=1e-12)
    assert e["peak_time"] == e["peak_time_ref"] == 0.25 and e["arrival_diff_s"] == 0.0
    # shifted by one coarse row: the peak arrives 0.025 s late
    late = accuracy.probe_errors(t[:-2] + 0.025, np.sin(2 * np.pi * t[:-2]), t_ref, y_ref)
    assert late["arrival_diff_s"] == pytest.approx(0.025, abs=1e-15)
    assert accuracy.relative_linf(t + 5.0, y, t_ref, y_ref) is None  # no common time


# -- collect on synthetic results folders -------------------------------------------

CASE = {
    "title": "synthetic",
    "time": {"end": 1.0, "dt": None},
    "mesh": {"nz": 10, "nr": 2, "order": 2},
    "fluid": {"model": "navier-stokes", "density": 1.0, "viscosity": 0.035},
    "coupler": {"model": None},
    "output": {"every": 0, "probes": [{"name": "eta_a", "quantity": "eta", "z": 1.0, "r": None, "line": 0},
                                      {"name": "eta_b", "quantity": "eta", "z": 2.0, "r": None, "line": 0}]},
}
T = np.linspace(0.01, 1.0, 100)
SHAPE = np.sin(np.pi * T) ** 2  # max 1 at t = 0.5


def write_run(folder, model, dt, amplitude, wall, order=None, viscosity=0.035):
    """A results folder whose η at both probes is amplitude·SHAPE (probe b: half of it, on the same rows)."""
    folder.mkdir(parents=True)
    case = json.loads(json.dumps(CASE))
    case["time"]["dt"], case["coupler"]["model"], case["fluid"]["viscosity"] = dt, model, viscosity
    summary = {"status": "ok", "reason": "", "case": case, "steps": round(1.0 / dt), "wall_time_s": wall,
               "dofs": {"wall": 10, "fluid": 100}}
    if order is not None:
        summary["scheme"] = {"name": "synthetic", "order": order}
    (folder / "summary.json").write_text(json.dumps(summary))
    with open(folder / "series.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["step", "t", "eta_a", "eta_b"])
        for i, (t, s) in enumerate(zip(T, SHAPE)):
            writer.writerow([i + 1, repr(float(t)), repr(float(amplitude * s)), repr(float(0.5 * amplitude * s))])


def test_collect_picks_the_higher_order_reference_and_measures_against_it(tmp_path):
    ks = planning.CouplerChoice("kinematic-splitting", "kinematic-splitting", "coupler=kinematic-splitting")
    mono = planning.CouplerChoice("mono[scheme=cn]", "mono", 'coupler={model="mono",scheme="cn"}')
    dts = ["4e-4", "2e-4", "1e-4"]
    planned = planning.plan(Path("c.toml"), [ks, mono], [("time.dt", dts)])
    amplitude = {"kinematic-splitting": lambda h: 1.0 + 300.0 * h, "mono": lambda h: 1.0 + 1e5 * h**2}
    walls = {("kinematic-splitting", "4e-4"): 1.0, ("kinematic-splitting", "2e-4"): 2.0,
             ("kinematic-splitting", "1e-4"): 4.0, ("mono", "4e-4"): 20.0, ("mono", "2e-4"): 10.0,
             ("mono", "1e-4"): 40.0}
    for p in planned:
        model = "kinematic-splitting" if p.coupler == ks.label else "mono"
        dt = p.values[0][1]
        write_run(tmp_path / p.folder, model, float(dt), amplitude[model](float(dt)), walls[model, dt],
                  order=2 if model == "mono" else None)
    # one more run that is not the same scene: measured but never compared
    odd = planning.Planned(Variant("odd", Path("c.toml")), "odd", ks.label, (("time.dt", "1e-3"),))
    write_run(tmp_path / "odd", "kinematic-splitting", 1e-3, 1.0, 0.5, viscosity=0.04)
    planned.append(odd)
    runs = {p.label: read_run(p.label, tmp_path / p.folder) for p in planned}
    data = study.collect(planned, runs, [ks, mono])

    ref = data["reference"]
    assert ref["label"] == "mono[scheme=cn]/time.dt=1e-4" and ref["order"] == 2  # listed second, higher order
    rows = {r["label"]: r for r in data["runs"]}
    a_ref = amplitude["mono"](1e-4)
    error = {}
    for label, row in rows.items():
        if label == ref["label"]:
            assert row["reference"] and row["error"] is None
            continue
        if label == "odd":
            assert not row["compared"] and "fluid.viscosity" in row["not_compared"] and row["error"] is None
            continue
        a = amplitude[row["model"]](row["dt"])
        error[label] = expected = abs(a - a_ref) / a_ref  # same rows, same shape: the amplitudes' difference
        assert row["error"] == pytest.approx(expected, rel=1e-12)
        assert row["peak_error"] == pytest.approx(expected, rel=1e-12)
        assert row["probes"]["eta_b"]["relative_linf"] == pytest.approx(expected, rel=1e-12)
        assert row["probes"]["eta_a"]["arrival_diff_s"] == 0.0
    orders = {(o["coupler"], o["dt_coarse"]): o for o in data["orders"]}
    assert set(orders) == {("kinematic-splitting", 4e-4), ("kinematic-splitting", 2e-4), ("mono[scheme=cn]", 4e-4)}
    e_ks = [error[f"kinematic-splitting/time.dt={dt}"] for dt in dts]
    p_fine = math.log2(e_ks[1] / e_ks[2])
    assert orders[("kinematic-splitting", 2e-4)]["peak_error_order"] == pytest.approx(p_fine, rel=1e-12)
    assert 0.9 < p_fine < 1.1  # first order against a reference of much smaller error
    # Richardson from the mono runs: successive differences of X = 1 + 1e5 Δt², relative to the finer
    x = [amplitude["mono"](float(h)) for h in dts]
    d_coarse, d_fine = abs(x[0] - x[1]) / x[1], abs(x[1] - x[2]) / x[2]
    p = math.log2(d_coarse / d_fine)
    rich = ref["richardson"]["error"]
    assert rich["order_from"] == "observed" and rich["order"] == pytest.approx(p, rel=1e-12)
    assert rich["estimate"] == pytest.approx(d_fine / (2**p - 1), rel=1e-12)
    assert rich["estimate"] == pytest.approx(x[2] - 1.0, rel=0.01)  # the reference's true error
    # mono at 4e-4 (20 s) is slower and less accurate than mono at 2e-4 (10 s)
    assert data["pareto"] == ["kinematic-splitting/time.dt=4e-4", "kinematic-splitting/time.dt=2e-4",
                              "kinematic-splitting/time.dt=1e-4", "mono[scheme=cn]/time.dt=2e-4"]
    costs = {(c["coupler"], c["target"]): c for c in data["cost_to_target"]}
    assert e_ks[2] < 0.05 < e_ks[1] and min(e_ks) > 0.01
    assert costs["kinematic-splitting", 0.05] == {
        "coupler": "kinematic-splitting", "model": "kinematic-splitting", "target": 0.05, "how": "measured",
        "wall_time_s": 4.0, "order": None, "run": "kinematic-splitting/time.dt=1e-4", "ratio_to_baseline": 1.0}
    ks_1 = costs["kinematic-splitting", 0.01]
    assert ks_1["how"] == "estimated" and ks_1["run"] == "kinematic-splitting/time.dt=1e-4"
    assert ks_1["wall_time_s"] == pytest.approx(4.0 * (e_ks[2] / 0.01) ** (1 / p_fine), rel=1e-12)
    for target in (0.05, 0.01):  # both mono runs meet it: the cheaper one, 2e-4, counts
        mono_cost = costs["mono[scheme=cn]", target]
        assert (mono_cost["how"], mono_cost["run"]) == ("measured", "mono[scheme=cn]/time.dt=2e-4")
        assert mono_cost["ratio_to_baseline"] == pytest.approx(
            10.0 / costs["kinematic-splitting", target]["wall_time_s"], rel=1e-12)


# -- bad input ------------------------------------------------------------------------


def study_argv(out, *extra, case=PULSE):
    return ["study", str(case), "--out", str(out), *extra]


@pytest.mark.parametrize(
    "extra, messages",
    [
        (["--couplers", "kinematic-splittin"], ["--couplers = 'kinematic-splittin'", "no such coupler plugin",
                                               "did you mean 'kinematic-splitting'?"]),
        (["--couplers", "kinematic-splitting,42"], ["--couplers = '42'", "expected a coupler name or an inline table"]),
        (["--couplers", '{scheme="cn"}'], ["--couplers = '{scheme=\"cn\"}'", "expected a coupler name"]),
        (["--couplers", '{model="kinematic-splitting"'], ["--couplers", "unbalanced '{'"]),
        (["--vary", "time.dt"], ["--vary = 'time.dt'", "expected KEY=A,B[,C...]"]),
        (["--vary", "time.dt=1e-4,,5e-5"], ["--vary = 'time.dt=1e-4,,5e-5'", "an empty value"]),
        (["--vary", "coupler=a,b"], ["--vary = 'coupler=a,b'", "chosen with --couplers"]),
        (["--jobs", "0"], ["--jobs = 0", "expected an integer >= 1"]),
    ],
)
def test_bad_input_exits_2_naming_the_key_and_the_value(tmp_path, capsys, extra, messages):
    out = tmp_path / "study"
    assert main(study_argv(out, *extra)) == 2
    err = capsys.readouterr().err
    assert "study: invalid command line" in err and "Traceback" not in err
    for message in messages:
        assert message in err
    assert not out.exists()


def test_a_coupler_name_and_a_coupler_table_are_the_same_override():
    from multilayer.case.casefile import load_case

    plain = load_case(PULSE)
    for item in planning.parse_couplers('kinematic-splitting,{model="kinematic-splitting"}', ["kinematic-splitting"]):
        case = load_case(PULSE, [item.override])
        assert case.digest == plain.digest and case.coupler.model == "kinematic-splitting"


def test_an_invalid_coupler_parameter_is_listed_per_run(tmp_path, capsys):
    out = tmp_path / "study"
    code = main(study_argv(out, "--couplers", 'kinematic-splitting,{model="kinematic-splitting",gamma=0.5}',
                           "--vary", "time.dt=1e-4,5e-5"))
    assert code == 2
    err = capsys.readouterr().err
    assert "study: 2 of 4 runs invalid" in err
    assert "kinematic-splitting[gamma=0.5]/time.dt=5e-5: coupler.gamma = 0.5: unknown key" in err
    assert not out.exists()


# -- end to end --------------------------------------------------------------------------

TINY = ["mesh.nz=12", "mesh.nr=3", "time.end=0.004"]
DTS = ["4e-4", "2e-4", "1e-4"]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("study")
    argv = study_argv(out, "--couplers", "kinematic-splitting", "--vary", "time.dt=" + ",".join(DTS), "--jobs", "2")
    for s in TINY:
        argv += ["--set", s]
    return main(argv), out, json.loads((out / "study.json").read_text())


def test_small_study_writes_every_output_and_every_run_is_ok(tiny, capfd):
    code, out, data = tiny
    assert code == 0
    for name in ("study.json", "study.md", "pareto.png", "orders.png"):
        assert (out / name).stat().st_size > 0
    assert [r["label"] for r in data["runs"]] == [f"kinematic-splitting/time.dt={dt}" for dt in DTS]
    for row, dt in zip(data["runs"], DTS):
        assert row["status"] == "ok"
        summary = json.loads((out / "kinematic-splitting" / f"time.dt={dt}" / "summary.json").read_text())
        assert summary["dt"] == row["dt"] == float(dt) and row["wall_time_s"] == summary["wall_time_s"]
        assert summary["case"]["mesh"]["nz"] == 12
    assert data["reference"]["label"] == "kinematic-splitting/time.dt=1e-4"
    assert data["command"].startswith("multilayer study ") and "--jobs 2" in data["command"]
    assert data["command"] in (out / "study.md").read_text()


def test_small_study_errors_are_the_series_own(tiny):
    _, out, data = tiny
    ref = read_run("ref", out / "kinematic-splitting" / "time.dt=1e-4")
    coarse = data["runs"][0]
    run = read_run("coarse", out / coarse["folder"])
    # every row of the coarse run is a row of the reference (4e-4 = 4 × 1e-4): no interpolation
    rows = np.searchsorted(ref.t, run.t - 1e-12)
    np.testing.assert_allclose(ref.t[rows], run.t, rtol=1e-12)
    etas = [p["name"] for p in run.probes if p["quantity"] == "eta"]
    assert len(etas) == 5
    errors = [np.max(np.abs(run.series[n] - ref.series[n][rows])) / np.max(np.abs(ref.series[n])) for n in etas]
    assert coarse["error"] == pytest.approx(max(errors), rel=1e-12)
    peaks = [abs(run.series[n].max() - ref.series[n].max()) / ref.series[n].max() for n in etas]
    assert coarse["peak_error"] == pytest.approx(max(peaks), rel=1e-12)


def test_small_study_has_a_positive_order_and_a_front(tiny):
    _, out, data = tiny
    (order,) = data["orders"]
    assert (order["dt_coarse"], order["dt_fine"]) == (4e-4, 2e-4)
    assert order["error_order"] > 0.0 and order["peak_error_order"] > 0.0
    e = [r["error"] for r in data["runs"][:2]]
    assert order["error_order"] == pytest.approx(math.log2(e[0] / e[1]), rel=1e-12)
    assert data["pareto"]  # at least the cheapest measured run
    assert data["reference"]["richardson"]["estimated"]
    costs = data["cost_to_target"]
    assert [c["target"] for c in costs] == [0.05, 0.01] and all(c["ratio_to_baseline"] == 1.0 for c in costs)
    assert "## Pareto front" in (out / "study.md").read_text()


def test_a_failed_run_is_reported_and_the_reference_case_runs_into_its_folder(tmp_path, capsys):
    out = tmp_path / "study"
    code = main(study_argv(out, "--vary", "loads.interface=0,-3e3", "--reference", str(MEMBRANE),
                           "--set", "time.end=0.01", "--set", "mesh.nz=8", case=MEMBRANE))
    assert code == 1
    data = json.loads((out / "study.json").read_text())
    ok, failed = data["runs"]
    assert data["reference"]["label"] == "reference" and (out / "reference" / "series.csv").is_file()
    assert not data["reference"]["richardson"]["estimated"]  # one ok run of the reference's scene: no Δt ratio
    assert ok["status"] == "ok" and ok["compared"] and ok["error"] == 0.0  # the same scene as the reference
    assert failed["status"] == "failed" and "wall collapse" in failed["reason"] and failed["error"] is None
    err = capsys.readouterr().err
    assert "structure-only/loads.interface=-3e3: failed (wall collapse" in err
    assert "[3/3]" in err and "study: 1 run(s) failed" in err
    assert "| failed |" in (out / "study.md").read_text()


def test_reference_set_makes_the_reference_from_the_case(tmp_path):
    """--reference-set alone: the study's case with those overrides is the reference, run once."""
    out = tmp_path / "refset"
    code = main(["study", str(CASES / "membrane-mode.toml"), "--out", str(out), "--set", "time.end=2e-4",
                 "--vary", "time.dt=1e-4,5e-5", "--reference-set", "time.dt=2.5e-5"])
    assert code == 0
    data = json.loads((out / "study.json").read_text())
    assert data["reference"]["source"] == "--reference" and data["reference"]["dt"] == 2.5e-5
    assert json.loads((out / "reference" / "summary.json").read_text())["steps"] == 8


def test_probes_and_reuse(tmp_path, capsys):
    """--probes measures at the named η probes only; --reuse runs nothing that already ended ok."""
    out = tmp_path / "pr"
    argv = ["study", str(CASES / "pulse-koiter.toml"), "--out", str(out), "--vary", "time.dt=4e-4,2e-4"]
    for s in ("mesh.nz=12", "mesh.nr=3", "time.end=0.002"):
        argv += ["--set", s]
    assert main([*argv, "--probes", "eta_z1,eta_z2"]) == 0
    data = json.loads((out / "study.json").read_text())
    assert data["probes"] == ["eta_z1", "eta_z2"]
    assert all(set(r["probes"]) <= {"eta_z1", "eta_z2"} for r in data["runs"])
    capsys.readouterr()
    assert main([*argv, "--reuse"]) == 0
    err = capsys.readouterr().err
    assert err.count("[reused]") == 2 and "[1/" not in err  # nothing ran again
    assert main([*argv, "--probes", "eta_z9"]) == 2
    assert "--probes = 'eta_z9': not an η probe" in capsys.readouterr().err
