"""``multilayer stability``: the measurements on series with known answers, bad input, one small map end to end."""

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from multilayer.campaign import stability, stability_report
from multilayer.campaign.planning import Planned
from multilayer.campaign.variants import Variant
from multilayer.case.casefile import load_case
from multilayer.commands.main import main
from multilayer.coupling.build import prepare
from multilayer.plugin.registry import Registry
from multilayer.results.reading import read_run, read_series
from multilayer.runner import ledger
from multilayer.runner.loop import run_case

CASES = Path(__file__).parents[1] / "cases"
PULSE = CASES / "pulse-koiter.toml"
# pulse-koiter.toml made tiny: 2 cm of channel, 8 × 2 cells, one probe inside it
TINY = ["geometry.length=2.0", "mesh.nz=8", "mesh.nr=2", "time.end=0.002",
        'output.probes=[{name="eta_z1",quantity="eta",z=1.0}]']


# -- the measurements on synthetic series -------------------------------------------------


def ledger_series(e0, stored, work, dissipation, residual=None):
    """series.csv columns of a run whose ledger the runner closed step by step (multilayer.runner.ledger.close)."""
    rows, previous = [], e0
    for n, (e, w, d) in enumerate(zip(stored, work, dissipation)):
        row = ledger.close({"kinetic.fluid": e}, previous, {"work.inlet": w[0], "work.outlet": w[1]},
                           {"dissipation.viscous.fluid": d[0], "dissipation.splitting": d[1]})
        if residual is not None:  # round-off as the runner would see it: the ledger closes to it
            row["energy.residual"] = residual[n]
        previous = row["energy.total"]
        rows.append({"t": 1e-4 * (n + 1), **row})
    return {k: np.array([r[k] for r in rows]) for k in rows[0]}


def test_a_dissipative_run_stays_below_the_work_put_in():
    # E0 = 2; each step puts in 1 (1.25 in, 0.25 out) and dissipates 0.5: Eₙ = 2 + 0.5 n
    series = ledger_series(2.0, [2.5, 3.0, 3.5, 4.0], [(1.25, -0.25)] * 4, [(0.4, 0.1)] * 4)
    assert stability.initial_energy(series) == pytest.approx(2.0, abs=1e-15)
    np.testing.assert_allclose(stability.energy_excess(series), [-0.5, -1.0, -1.5, -2.0], atol=1e-14)
    # max over steps: the first, −0.5, over |E0| + max |Wₙ| = 2 + 4
    assert stability.energy_growth(series) == pytest.approx(-0.5 / 6.0, rel=1e-14)
    assert stability.is_stable("ok", stability.energy_growth(series))


def test_energy_beyond_e0_plus_the_work_at_one_step_is_unstable():
    # step 3 makes 0.75 of energy (a negative splitting "dissipation"), the other steps dissipate 0.5
    series = ledger_series(2.0, [2.5, 3.0, 4.75, 5.25], [(1.25, -0.25)] * 4,
                           [(0.4, 0.1), (0.4, 0.1), (0.4, -1.15), (0.4, 0.1)])
    np.testing.assert_allclose(stability.energy_excess(series), [-0.5, -1.0, -0.25, -0.75], atol=1e-14)
    assert stability.energy_growth(series) < 0  # still below: the earlier dissipation covers it
    series = ledger_series(2.0, [2.5, 3.0, 5.25, 5.75], [(1.25, -0.25)] * 4,
                           [(0.4, 0.1), (0.4, 0.1), (0.4, -1.65), (0.4, 0.1)])
    # Eₙ − E0 − Wₙ = 5.25 − 2 − 3 = 0.25 at step 3, the largest: 0.25 / (2 + 4)
    assert stability.energy_growth(series) == pytest.approx(0.25 / 6.0, rel=1e-13)
    assert not stability.is_stable("ok", stability.energy_growth(series))
    assert stability.verdict("ok", stability.energy_growth(series)) == "energy grew"


def test_initial_energy_takes_the_first_residual_and_the_threshold_is_round_off():
    # a first row whose ledger residual is 1e-12: E0 = E1 − W1 + D1 − residual1
    series = ledger_series(3.0, [3.5, 3.9], [(1.0, 0.0)] * 2, [(0.5, 0.0), (0.6, 0.0)])
    series["energy.total"] = series["energy.total"] + 1e-12
    series["energy.residual"] = series["energy.residual"] + 1e-12
    assert stability.initial_energy(series) == pytest.approx(3.0, abs=1e-15)
    assert stability.is_stable("ok", 1e-9) and not stability.is_stable("ok", 2e-9)
    assert not stability.is_stable("failed", -1.0) and not stability.is_stable("ok", None)
    assert stability.energy_growth({"t": np.zeros(0), "energy.total": np.zeros(0)}) is None
    blown = ledger_series(0.0, [1.0, np.inf], [(1.0, 0.0)] * 2, [(0.0, 0.0)] * 2)
    assert stability.energy_growth(blown) == np.inf and not stability.is_stable("ok", np.inf)


def test_the_density_realises_the_ratio():
    # pulse-koiter.toml: ρ₁ = 1.1, h = 0.1, ρ_f = 1, R = 0.5 → ρ₁h/(ρ_f R) = 0.22
    assert stability.mass_ratio(1.1, 0.1, 1.0, 0.5) == pytest.approx(0.22, rel=1e-15)
    for ratio in (1.0, 0.1, 0.01, 1e-3, 0.22):
        rho = stability.density_for_ratio(ratio, 1.0, 0.5, 0.1)
        assert rho == pytest.approx(ratio * 1.0 * 0.5 / 0.1, rel=1e-15)
        assert stability.mass_ratio(rho, 0.1, 1.0, 0.5) == pytest.approx(ratio, rel=1e-14)
    assert stability.density_for_ratio(1e-3, 1.06, 0.3, 0.02) == pytest.approx(1e-3 * 1.06 * 0.3 / 0.02, rel=1e-15)


def test_iterations_from_the_column_or_one_per_step():
    it = stability.iteration_counts({"t": np.arange(4.0), "iterations": np.array([2.0, 7.0, 3.0, 4.0])})
    assert it == {"reported": True, "total": 16, "mean": 4.0, "max": 7}
    assert stability.iteration_counts({"t": np.arange(3.0)}) == {"reported": False, "total": 3, "mean": 1.0, "max": 1}


def test_initial_energy_is_the_couplers_own_on_a_run_from_a_displaced_wall(tmp_path):
    """E0 from the first row equals the energy the coupler reports for the initial state (not 0)."""
    registry = Registry.load()
    case = load_case(PULSE, [*TINY, "time.end=5e-4", "loads.inlet=0.0",
                             'initial.displacement={r="0.01*sin(pi*z/2)", z="0"}'], registry)
    setup, coupler = prepare(case, registry)
    e0 = sum(coupler.energy(setup, coupler.initial_state(setup)).values())
    assert e0 > 1.0
    assert run_case(case, tmp_path, registry).status == "ok"
    series = read_series(tmp_path / "series.csv")
    assert stability.initial_energy(series) == pytest.approx(e0, rel=1e-13)
    assert stability.energy_growth(series) < 0  # a free, viscous wall loses energy


# -- collecting and reporting on synthetic results folders -------------------------------------


def write_folder(folder, status, energy, iterations=None, reason=""):
    """A results folder: a case with a Koiter shell of ρ₁ = 0.5 (ratio 0.1), the given ledger rows."""
    folder.mkdir(parents=True)
    case = {"title": "synthetic", "time": {"end": 4e-4, "dt": 1e-4}, "geometry": {"length": 2.0, "radius": 0.5},
            "fluid": {"model": "navier-stokes", "density": 1.0, "viscosity": 0.035},
            "layers": [{"model": "koiter-shell", "density": 0.5, "thickness": 0.1}],
            "coupler": {"model": "dn"}}
    summary = {"status": status, "reason": reason, "case": case, "steps": len(energy), "wall_time_s": 2.5}
    (folder / "summary.json").write_text(json.dumps(summary))
    columns = ["step", "t", "work.inlet", "dissipation.viscous.fluid", "energy.total", "energy.residual"]
    with open(folder / "series.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(columns + (["iterations"] if iterations else []))
        previous = 0.0
        for n, e in enumerate(energy):
            row = [n + 1, 1e-4 * (n + 1), 1.0, previous + 1.0 - e, e, 0.0]  # dissipation closes the ledger
            writer.writerow(row + ([iterations[n]] if iterations else []))
            previous = e


def test_measure_and_report_a_stable_a_failed_and_an_unstable_run(tmp_path):
    rows = []
    for name, status, energy, iterations, reason in [
        ("stable", "ok", [0.9, 1.8, 2.7, 3.6], [3, 5, 4, 4], ""),
        ("failed", "failed", [0.9, 1.8], [6, 30], "energy grew beyond the work put in at t = 0.0003 s"),
        ("grew", "ok", [0.9, 1.8, 3.5, 4.0], None, ""),
    ]:
        folder = tmp_path / "dn" / "ratio=0.1" / name
        write_folder(folder, status, energy, iterations, reason)
        planned = Planned(Variant(f"dn/ratio=0.1/{name}", PULSE), f"dn/ratio=0.1/{name}", "dn",
                          (("ratio", "0.1"), ("case", name)))
        rows.append(stability.measure_run(planned, read_run(planned.label, folder), 0))
    stable, failed, grew = rows
    assert stable["stable"] and stable["verdict"] == "stable"
    assert stable["iterations"] == {"reported": True, "total": 16, "mean": 4.0, "max": 5}
    assert stable["energy_growth"] == pytest.approx(-0.1 / 4.0, rel=1e-12)  # −D1 over E0 + W4 = 0 + 4
    assert stable["density"] == 0.5 and stable["ratio_realised"] == pytest.approx(0.1, rel=1e-15)
    assert (stable["steps"], stable["steps_planned"], stable["ratio"]) == (4, 4, 0.1)
    assert failed["verdict"] == "failed" and not failed["stable"] and failed["failure_time_s"] == pytest.approx(2e-4)
    assert failed["steps"] == 2 and "t = 0.0003 s" in failed["reason"]
    # E3 = 3.5 > E0 + W3 = 3 (its dissipation is −0.7): 0.5 over 4
    assert grew["verdict"] == "energy grew" and grew["energy_growth"] == pytest.approx(0.5 / 4.0, rel=1e-12)
    assert grew["energy_growth_time_s"] == pytest.approx(3e-4) and not grew["iterations"]["reported"]

    assert stability_report.status_cell(stable) == "stable, 4.0 it/step (max 5), 2.5 s"
    assert stability_report.status_cell(failed) == "failed after t = 0.0002 s"
    assert stability_report.status_cell(grew) == "energy grew (1.25e-01), 1.0 it/step, 2.5 s"
    data = {"command": "multilayer stability x", "title": "synthetic", "tolerance": 1e-9,
            "layer": {"index": 0, "path": "layers[0]", "model": "koiter-shell", "thickness": 0.1},
            "fluid_density": 1.0, "radius": 0.5, "ratios": [{"text": "0.1", "ratio": 0.1, "density": 0.5}],
            "couplers": [{"label": "dn"}], "runs": rows}
    text = stability_report.markdown(data)
    assert text.count("## Δt = 0.0001 s, case = ") == 3 and "| `dn` | failed after t = 0.0002 s |" in text
    assert "energy grew beyond the work put in at t = 0.0003 s" in text and "No `iterations` column" in text
    stability_report.plot(data, tmp_path / "stability.png")
    assert (tmp_path / "stability.png").stat().st_size > 0


# -- bad input ---------------------------------------------------------------------------------


def stability_argv(out, *extra, case=PULSE):
    return ["stability", str(case), "--out", str(out), *extra]


@pytest.mark.parametrize(
    "extra, case, messages",
    [
        (["--couplers", "monolitic"], PULSE, ["--couplers = 'monolitic'", "no such coupler plugin",
                                              "did you mean 'monolithic'?"]),
        (["--ratios", "1,0,-0.1"], PULSE, ["--ratios = '0': expected a number > 0",
                                          "--ratios = '-0.1': expected a number > 0"]),
        (["--ratios", "1,abc,1e-3,0.001"], PULSE, ["--ratios = 'abc': expected a number > 0",
                                                  "--ratios = '0.001': given twice"]),
        (["--layer", "1"], PULSE, ["--layer = 1: expected a layer index 0..0", "thin layers here: layers[0]"]),
        (["--layer", "1"], CASES / "pulse-koiter-thick.toml",
         ["--layer = 1: layers[1] is a thick layer (linear-elastic)", "thin layers here: layers[0] (koiter-shell)"]),
        ([], CASES / "membrane-mode.toml", ["fluid: the mass ratio ρ₁h/(ρ_f R) needs a fluid"]),
        (["--vary", "time.dt"], PULSE, ["--vary = 'time.dt': expected KEY=A,B[,C...]"]),
        (["--vary", "geometry.radius=0.4,0.5"], PULSE, ["--vary = 'geometry.radius=0.4,0.5': the ratios set "
                                                        "layers[0].density"]),
        (["--vary", "layers[0]={model=\"koiter-shell\"},{model=\"wave-membrane\"}"], PULSE,
         ["--vary = 'layers[0]={model=\"koiter-shell\"},{model=\"wave-membrane\"}': the ratios set"]),
        (["--jobs", "0"], PULSE, ["--jobs = 0: expected an integer >= 1"]),
    ],
)
def test_bad_input_exits_2_naming_the_key_and_the_value(tmp_path, capsys, extra, case, messages):
    out = tmp_path / "map"
    assert main(stability_argv(out, *extra, case=case)) == 2
    err = capsys.readouterr().err
    assert "stability: invalid command line" in err and "Traceback" not in err
    for message in messages:
        assert message in err
    assert not out.exists()


def test_an_invalid_run_is_listed_before_anything_runs(tmp_path, capsys):
    out = tmp_path / "map"
    code = main(stability_argv(out, "--couplers", '{model="monolithic",scheme="euler"}', "--ratios", "0.1"))
    assert code == 2
    err = capsys.readouterr().err
    assert "stability: 1 of 1 runs invalid" in err and "monolithic[scheme=euler]/ratio=0.1: coupler.scheme" in err
    assert not out.exists()


# -- end to end --------------------------------------------------------------------------------

COUPLERS = ["kinematic-splitting", "monolithic"]
RATIOS = ["1", "0.001"]
DTS = ["2e-4", "1e-4"]


@pytest.fixture(scope="module")
def tiny_map(tmp_path_factory):
    out = tmp_path_factory.mktemp("stability")
    argv = stability_argv(out, "--couplers", 'kinematic-splitting,{model="monolithic"}', "--ratios", ",".join(RATIOS),
                          "--vary", "time.dt=" + ",".join(DTS), "--jobs", "2")
    for s in TINY:
        argv += ["--set", s]
    return main(argv), out, json.loads((out / "stability.json").read_text())


def test_small_map_writes_every_output_and_every_run_is_stable(tiny_map, capfd):
    code, out, data = tiny_map
    assert code == 0
    for name in ("stability.json", "stability.md", "stability.png"):
        assert (out / name).stat().st_size > 0
    assert [r["text"] for r in data["ratios"]] == RATIOS
    assert [r["density"] for r in data["ratios"]] == [pytest.approx(5.0), pytest.approx(0.005)]
    assert [(r["coupler"], r["ratio"], r["values"]["time.dt"]) for r in data["runs"]] == [
        (c, float(r), dt) for c in COUPLERS for r in RATIOS for dt in DTS]
    for row in data["runs"]:
        assert row["stable"] and row["status"] == "ok" and row["verdict"] == "stable"
        assert row["energy_growth"] <= stability.GROWTH_TOLERANCE
        assert row["steps"] == row["steps_planned"] == round(0.002 / row["dt"])
        assert row["iterations"] == {"reported": False, "total": row["steps"], "mean": 1.0, "max": 1}
        summary = json.loads((out / row["folder"] / "summary.json").read_text())
        assert summary["case"]["layers"][0]["density"] == row["density"]
        assert row["ratio_realised"] == pytest.approx(row["ratio"], rel=1e-14)
        assert row["wall_time_s"] == summary["wall_time_s"]
        # the growth is the series' own: Eₙ − E0 − Wₙ over |E0| + max |Wₙ|, E0 = 0 (from rest)
        series = read_series(out / row["folder"] / "series.csv")
        work = np.cumsum(sum(v for k, v in series.items() if k.startswith("work.")))
        assert row["energy_initial"] == pytest.approx(0.0, abs=1e-12 * work.max())
        assert row["energy_growth"] == pytest.approx(np.max(series["energy.total"] - work) / work.max(), rel=1e-6)
    assert (out / "monolithic" / "ratio=0.001" / "time.dt=1e-4" / "series.csv").is_file()


def test_small_map_report_has_the_command_and_a_table_per_dt(tiny_map):
    _, out, data = tiny_map
    text = (out / "stability.md").read_text()
    assert data["command"].startswith("multilayer stability ") and "--jobs 2" in data["command"]
    assert text.splitlines()[2] == "    " + data["command"]
    assert "## Δt = 0.0002 s" in text and "## Δt = 0.0001 s" in text
    assert text.count("| `kinematic-splitting` | stable, 1.0 it/step, ") == 2
    assert "None: every run is stable." in text


def test_the_small_stability_map_shows_the_qualitative_facts(tmp_path):
    """The CI version of docs/stability.md's map (8 × 2 cells, 20 steps of 1e-4 s).

    Explicit Dirichlet–Neumann fails at the lightest wall; kinematic splitting,
    its second-order variant and monolithic are stable at every ratio; implicit
    Dirichlet–Neumann converges, its iterations growing as the wall gets
    lighter, Aitken's more than IQN-ILS's.
    """
    couplers = ['"dirichlet-neumann-explicit"', '"kinematic-splitting"',
                '{model="kinematic-splitting",scheme="crank-nicolson",beta=1}',
                '{model="monolithic",scheme="crank-nicolson"}', '"dirichlet-neumann-implicit"',
                '{model="dirichlet-neumann-implicit",acceleration="aitken",max_iterations=1000}']
    out = tmp_path / "map"
    code = main(["stability", str(CASES / "pulse-koiter.toml"), "--out", str(out), "--couplers", ",".join(couplers),
                 "--jobs", "2", *sum((["--set", s] for s in (
                     "geometry.length=2.0", "mesh.nz=8", "mesh.nr=2", "time.end=0.002", "time.dt=1e-4",
                     'output.probes=[{name="eta_z1",quantity="eta",z=1.0}]')), [])])
    assert code == 0
    runs = json.loads((out / "stability.json").read_text())["runs"]

    def verdicts(model, **params):
        picked = [r for r in runs if r["model"] == model
                  and all(str(v) in r["coupler"] for v in params.values())
                  and ("scheme=" in r["coupler"]) == ("scheme" in params)
                  and ("acceleration=" in r["coupler"]) == ("acceleration" in params)]
        return {r["ratio"]: r for r in picked}

    explicit = verdicts("dirichlet-neumann-explicit")
    assert explicit[0.001]["verdict"] == "failed"
    for model, params in (("kinematic-splitting", {}), ("kinematic-splitting", {"scheme": "crank-nicolson"}),
                          ("monolithic", {"scheme": "crank-nicolson"})):
        got = verdicts(model, **params)
        assert len(got) == 4 and all(r["verdict"] == "stable" for r in got.values()), (model, params)
    iqn, aitken = verdicts("dirichlet-neumann-implicit"), verdicts("dirichlet-neumann-implicit", acceleration="aitken")
    ratios = sorted(iqn, reverse=True)  # heaviest wall first
    for got in (iqn, aitken):
        assert all(got[r]["verdict"] == "stable" for r in ratios)
        mean = [got[r]["iterations"]["mean"] for r in ratios]
        assert all(b > a for a, b in zip(mean, mean[1:])), mean
    assert all(aitken[r]["iterations"]["mean"] > iqn[r]["iterations"]["mean"] for r in ratios)
