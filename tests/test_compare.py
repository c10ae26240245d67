"""``multilayer compare``: variants side by side, every reported number traceable to the runs' own files."""

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from multilayer.campaign import measures, variants
from multilayer.campaign.report import markdown
from multilayer.commands.main import main
from multilayer.plugin.registry import Registry
from multilayer.results import reading

CASES = Path(__file__).parents[1] / "cases"
MEMBRANE = CASES / "membrane-mode.toml"

# A Gaussian bump on a wave membrane splits into two pulses running at
# c = √(C1/(ρh)); the right-going one passes the probes at z = 2, 3, 4.
TRAVELLING = [
    "time.end=0.008",
    "time.dt=4e-5",
    "mesh.nz=32",
    'initial.displacement.r="0.01*exp(-((z-1)/0.2)**2)"',
    ('output.probes=[{name="eta_2",quantity="eta",z=2.0},{name="eta_3",quantity="eta",z=3.0},'
     '{name="eta_4",quantity="eta",z=4.0}]'),
    "output.every=10",
]


def compare_argv(out, *cases, vary=None, sets=()):
    argv = ["compare", *map(str, cases), "--out", str(out)]
    if vary is not None:
        argv += ["--vary", vary]
    for s in sets:
        argv += ["--set", s]
    return argv


def read_columns(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def md_table(path):
    """The report's table: row title → cells."""
    return md_table_text(path.read_text())


def md_table_text(text):
    lines = [line for line in text.splitlines() if line.startswith("| ")]
    return {cells[0]: cells[1:] for cells in ([c.strip() for c in line.strip("|").split(" | ")] for line in lines)}


def md_row(table, start):
    (key,) = [k for k in table if k.startswith(start)]
    return table[key]


@pytest.fixture(scope="module")
def tension(tmp_path_factory):
    out = tmp_path_factory.mktemp("tension")
    code = main(compare_argv(out, MEMBRANE, vary="layers[0].tension=2e4,8e4", sets=TRAVELLING))
    return code, out, json.loads((out / "report.json").read_text())


def test_vary_runs_each_value_into_its_own_results_folder(tension):
    code, out, report = tension
    assert code == 0
    for name in ("report.md", "report.json", "probes.png", "eta_spacetime.png"):
        assert (out / name).stat().st_size > 0
    assert [c["label"] for c in report["variants"]] == ["tension=2e4", "tension=8e4"]
    for column, c1 in zip(report["variants"], (2.0e4, 8.0e4)):
        summary = json.loads((out / column["out"] / "summary.json").read_text())
        assert summary["status"] == column["status"] == "ok"
        assert summary["case"]["layers"][0]["tension"] == c1
        assert summary["steps"] == column["steps"] == 200
    header = next(line for line in (out / "report.md").read_text().splitlines() if line.startswith("| |"))
    assert "`tension=2e4`" in header and "`tension=8e4`" in header


def test_reported_numbers_are_the_series_own(tension):
    _, out, report = tension
    a, b = (read_columns(out / c["out"] / "series.csv") for c in report["variants"])
    table = md_table(out / "report.md")
    assert np.array_equal(a["t"], b["t"])  # same steps: Δη is the plain row-by-row difference
    for name in ("eta_2", "eta_3", "eta_4"):
        expected = float(np.max(np.abs(a[name] - b[name])))
        got = report["variants"][1]["probes"][name]["max_abs_diff"]
        assert got == pytest.approx(expected, rel=1e-14, abs=0.0) and got > 1e-3
        assert md_row(table, f"max \\|Δη\\| vs `tension=2e4` at `{name}`") == ["(reference)", f"{expected:.4g}"]
        for column, series in zip(report["variants"], (a, b)):
            assert column["probes"][name]["peak_time"] == series["t"][np.argmax(np.abs(series[name]))]
    for column, series in zip(report["variants"], (a, b)):
        summary = json.loads((out / column["out"] / "summary.json").read_text())
        assert column["final_energy"] == series["energy.total"][-1]
        assert column["max_relative_residual"] == series["energy.relative_residual"].max()
        assert column["max_relative_residual"] == summary["energy"]["max_relative_residual"]
        assert column["dofs_total"] == summary["dofs"]["wall"]
    assert md_row(table, "final total energy") == [f"{c['final_energy']:.4g} erg/cm" for c in report["variants"]]


def test_four_times_the_tension_doubles_the_measured_speed(tension):
    _, _, report = tension
    slow, fast = (c["wave_speed_peak"] for c in report["variants"])
    assert fast / slow == pytest.approx(2.0, rel=0.01)
    exact = math.sqrt(2.0e4 / (1.1 * 0.1))
    assert slow == pytest.approx(exact, rel=0.02)
    assert [c["long_wave_speed"] for c in report["variants"]] == [None, None]  # no fluid


def test_spacetime_field_is_eta_on_the_lumen_line(tension):
    _, out, report = tension
    folder = out / report["variants"][1]["out"]
    z, t, eta = reading.lumen_eta(folder, radius=0.5)
    assert np.all(np.diff(z) > 0) and z[0] == 0.0 and z[-1] == 6.0
    series = read_columns(folder / "series.csv")
    j = int(np.argmin(abs(z - 3.0)))
    assert z[j] == 3.0
    rows = np.searchsorted(series["t"], t[1:] - 1e-12)  # the snapshot at t = 0 has no series row
    np.testing.assert_allclose(eta[1:, j], series["eta_3"][rows], rtol=0, atol=1e-15)


def synthetic_runs(tmp_path, zs, c, width, dt, precursor=None):
    """Two runs (Δt and 2Δt) whose η probes at ``zs`` see a triangular pulse of speed c arrive; ``precursor``
    (z, height) adds a probe whose η is a small early bump, peaking before the pulse reaches any probe."""
    names = [f"eta_{i}" for i in range(len(zs))] + (["eta_ahead"] if precursor else [])
    case = {
        "title": "synthetic",
        "geometry": {"length": 6.0, "radius": 0.5},
        "mesh": {"nz": 48, "nr": 2, "order": 2},
        "fluid": {"model": "navier-stokes", "density": 1.0, "viscosity": 0.035},
        "layers": [{"model": "koiter-shell", "density": 1.1, "thickness": 0.1, "C0": 4.0e5, "C1": 0.0, "C2": 0.0}],
        "output": {"probes": [{"name": name, "quantity": "eta", "z": z, "r": None, "line": 0}
                              for name, z in zip(names, [*zs, *(precursor[:1] if precursor else [])])]
                   + [{"name": "p_in", "quantity": "p", "z": 0.5, "r": 0.0, "line": None}]},
    }
    folders = []
    for label, step in (("fine", dt), ("coarse", 2 * dt)):
        t = step * np.arange(1, round(0.01 / step) + 1)
        columns = {"step": np.arange(1, len(t) + 1), "t": t}
        for i, z in enumerate(zs):
            columns[f"eta_{i}"] = 1e-3 * np.maximum(0.0, 1.0 - np.abs(t - z / c) / width)
        if precursor:
            columns["eta_ahead"] = precursor[1] * np.maximum(0.0, 1.0 - np.abs(t - 0.5 * zs[0] / c) / width)
        columns["p_in"] = 1e4 * np.sin(np.pi * t / 0.01)
        columns["energy.total"] = 1.0 + t
        columns["energy.relative_residual"] = 1e-15 * np.cos(t)
        folder = tmp_path / label
        folder.mkdir(parents=True)
        with open(folder / "series.csv", "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(columns)
            writer.writerows(zip(*(map(repr, map(float, v)) for v in columns.values())))
        (folder / "summary.json").write_text(json.dumps(
            {"status": "ok", "case": case, "steps": len(t), "wall_time_s": 1.0, "dofs": {"wall": 7, "fluid": 5}}))
        folders.append((label, folder))
    runs = [reading.read_run(label, folder) for label, folder in folders]
    return runs, measures.compare_runs(runs, Registry.load())


def test_synthetic_pulses_give_the_exact_speed(tmp_path):
    c, dt, width = 500.0, 1e-4, 5e-4
    zs = [1.0, 2.0, 3.5, 5.1]  # the last pulse is still rising on the last row (t = 0.01 < 5.1/c)
    runs, (fine, coarse) = synthetic_runs(tmp_path, zs, c, width, dt)
    for column in (fine, coarse):
        assert column["wave_speed_peak"] == pytest.approx(c, rel=1e-9)
        assert column["wave_speed_half_peak"] == pytest.approx(c, rel=1e-9)
        for i, z in enumerate(zs[:-1]):
            assert column["probes"][f"eta_{i}"]["half_peak_time"] == pytest.approx(z / c - width / 2, rel=1e-9)
            assert column["probes"][f"eta_{i}"]["peaked"]
        rising = column["probes"]["eta_3"]
        assert not rising["peaked"] and rising["peak_time"] == pytest.approx(0.01)
        # the shell's static compliance 1/C0 (C1 = C2 = 0; nz = 48: the pinned ends' ripple has died out mid-way)
        assert column["long_wave_speed"] == pytest.approx(math.sqrt(0.5 * 4.0e5 / 1.0), rel=1e-12)
        # the triangles rise in a straight line from z/c − width: their feet, and the speed, are exact
        assert column["pwv_foot_eta"] == pytest.approx(c, rel=1e-9) and column["pwv_foot_eta_reason"] == ""
        for i, z in enumerate(zs[:-1]):
            assert column["probes"][f"eta_{i}"]["foot_time"] == pytest.approx(z / c - width, rel=1e-9)
    # the last row cuts the last upstroke: three rows of its straight line (Δt) still give its foot, one (2Δt) not
    assert fine["probes"]["eta_3"]["foot_time"] == pytest.approx(zs[-1] / c - width, rel=1e-9)
    assert coarse["probes"]["eta_3"]["foot_reason"].startswith("the upstroke is still steepening on the last row")
    for column in (fine, coarse):
        assert column["pwv_foot_p"] is None
        assert column["pwv_foot_p_reason"] == ("fewer than two probes with a foot "
                                               "(p_in: the upstroke starts before the first row)")
        assert column["dofs_total"] == 12
    assert coarse["final_energy"] == 1.01
    assert fine["peak_pressure"] == pytest.approx(1e4) and fine["peak_pressure_probe"] == "p_in"
    # the coarse series sample the same piecewise-linear pulses at every other kink: Δη is exact
    # at the coarse rows, so the difference is the fine series' deviation from the coarse interpolant
    t_f, t_c = runs[0].t, runs[1].t
    for i in range(len(zs)):
        y_f, y_c = runs[0].series[f"eta_{i}"], runs[1].series[f"eta_{i}"]
        expected = np.max(np.abs(np.interp(t_f[t_f >= t_c[0]], t_c, y_c) - y_f[t_f >= t_c[0]]))
        assert coarse["probes"][f"eta_{i}"]["max_abs_diff"] == pytest.approx(expected, rel=1e-12)
        assert 0.0 < expected < 1e-3
    text = markdown({"title": "synthetic", "reference": "fine", "variants": [fine, coarse]})
    assert md_row(md_table_text(text), "peak time at `eta_3`") == ["0.01 (last row)"] * 2


def test_a_precursor_ahead_of_the_pulse_is_no_arrival(tmp_path):
    """A probe the pulse has not reached shows only what runs ahead of it, orders of magnitude smaller (a
    run cut at 1 ms on the tube, `multilayer sweep ... --vary layers[1].young=2e6,8e6`, had its fit turn
    on such a peak and print −15 000 cm/s).  Below 1 % of the largest η peak a peak is no arrival."""
    c, dt, width = 500.0, 1e-4, 5e-4
    zs = [1.0, 2.0, 3.5]
    _, (fine, _) = synthetic_runs(tmp_path / "small", zs, c, width, dt, precursor=(5.5, 1e-7))
    assert fine["wave_speed_peak"] == pytest.approx(c, rel=1e-9)
    assert fine["pwv_foot_eta"] == pytest.approx(c, rel=1e-9)
    assert "— (the pulse has not arrived: its rise is 0.0% of the largest)" == md_row(
        md_table_text(markdown({"title": "", "reference": "fine", "variants": [fine]})), "foot time at `eta_ahead`")[0]
    # at half the pulse's height the bump is fitted like any arrival, and the fit runs backwards: no speed, and why
    _, (fine, _) = synthetic_runs(tmp_path / "large", zs, c, width, dt, precursor=(5.5, 5e-4))
    assert fine["wave_speed_peak"] is None and fine["pwv_foot_eta"] is None
    assert fine["wave_speed_peak_reason"].startswith("the arrivals do not come later downstream")
    assert fine["pwv_foot_eta_reason"].startswith("the feet do not come later downstream")


def test_differences_interpolate_in_time():
    t_fine, t_coarse = np.linspace(0.1, 1.0, 10), np.linspace(0.2, 1.0, 5)
    assert measures.max_abs_difference(t_fine, 3 * t_fine, t_coarse, 3 * t_coarse) == pytest.approx(0.0, abs=1e-15)
    assert measures.max_abs_difference(t_fine, t_fine + 0.25, t_coarse, t_coarse) == pytest.approx(0.25)
    # the largest difference sits at a kink of one series only: both grids are needed
    t, flat = np.array([0.0, 2.0]), np.zeros(2)
    assert measures.max_abs_difference(t, flat, np.array([0.0, 1.0, 2.0]), np.array([0.0, 1.0, 0.0])) == 1.0
    assert measures.max_abs_difference(np.array([0.0, 1.0, 2.0]), np.array([0.0, 1.0, 0.0]), t, flat) == 1.0
    assert measures.max_abs_difference(t, flat, t + 3.0, flat) is None  # no common time


PULSE = CASES / "pulse-koiter-thick.toml"  # fluid | Koiter shell | thick band, inlet cosine pulse
COARSE = ["mesh.nz=12", "mesh.nr=2", "mesh.order=1", "time.end=0.002"]
WAVE = '{model="wave-membrane",density=1.1,thickness=0.02,tension=2e5}'
SHELL = '{model="koiter-shell",density=1.1,thickness=0.02,young=7.5e5,poisson=0.49}'


def test_wave_membrane_against_koiter_shell_by_whole_layer_tables(tmp_path):
    out = tmp_path / "cmp"
    assert main(compare_argv(out, PULSE, vary=f"layers[0]={WAVE},{SHELL}", sets=COARSE)) == 0
    report = json.loads((out / "report.json").read_text())
    wave, shell = report["variants"]
    assert (wave["label"], shell["label"]) == ("wave-membrane", "koiter-shell")
    series = {}
    for column, model in ((wave, "wave-membrane"), (shell, "koiter-shell")):
        folder = out / column["out"]
        summary = json.loads((folder / "summary.json").read_text())
        assert column["status"] == summary["status"] == "ok"
        assert [layer["model"] for layer in summary["case"]["layers"]] == [model, "linear-elastic"]
        assert summary["case"]["output"]["every"] == 1  # forced: the case writes no snapshots
        assert "output.every=1" in column["overrides"]
        assert len(list(folder.glob("wall_*.vtu"))) == 21
        series[model] = s = read_columns(folder / "series.csv")
        probes = summary["case"]["output"]["probes"]
        pressures = [p["name"] for p in probes if p["quantity"] == "p"]
        assert pressures and column["peak_pressure"] == max(s[name].max() for name in pressures)
        assert column["dofs_total"] == summary["dofs"]["wall"] + summary["dofs"]["fluid"]
    etas = [p["name"] for p in probes if p["quantity"] == "eta"]
    a, b = series["wave-membrane"], series["koiter-shell"]
    for name in etas:
        diff = shell["probes"][name]["max_abs_diff"]
        assert diff == pytest.approx(np.max(np.abs(a[name] - b[name])), rel=1e-14, abs=0.0)
    assert shell["probes"][etas[0]]["max_abs_diff"] > 0.0
    # C0 of the shell (theory §1), independently of the plugin; ρ_f = 1
    h, E, s, R = 0.02, 7.5e5, 0.49, 0.5
    c0 = h * E / (R**2 * (1 - s**2)) * (1 + h**2 / (12 * R**2))
    # the stack's: the shell's C0, and the band's clamped ends hold a little (the planar band has no hoop term)
    assert shell["long_wave_speed"] == pytest.approx(math.sqrt(R * c0 / 1.0), rel=1e-5)
    assert wave["long_wave_speed"] is None  # a membrane has C0 = 0: its ends and the band's carry the load
    assert "its ends carry part of the load" in wave["long_wave_speed_reason"]
    table = md_table(out / "report.md")
    assert md_row(table, "long-wave speed of the stack") == [f"— ({wave['long_wave_speed_reason']})",
                                                             f"{shell['long_wave_speed']:.4g}"]


def test_a_failed_variant_is_reported_with_its_reason(tmp_path, capsys):
    out = tmp_path / "cmp"
    code = main(compare_argv(out, MEMBRANE, vary="loads.interface=0,-3e3",
                             sets=["time.end=0.01", "mesh.nz=8", "output.every=50"]))
    assert code == 1
    report = json.loads((out / "report.json").read_text())
    ok, failed = report["variants"]
    assert ok["status"] == "ok" and failed["status"] == "failed"
    assert "wall collapse" in failed["reason"]
    series = read_columns(out / failed["out"] / "series.csv")
    assert 0 < failed["steps"] == len(series["t"]) < ok["steps"]
    assert failed["final_energy"] == series["energy.total"][-1]
    text = (out / "report.md").read_text()
    assert "| status | ok | failed |" in text and f"`{failed['label']}`: wall collapse" in text
    assert "failed: interface=-3e3" in capsys.readouterr().err


def test_invalid_variants_are_listed_by_label_and_nothing_runs(tmp_path, capsys):
    out = tmp_path / "cmp"
    assert main(compare_argv(out, MEMBRANE, vary="layers[0].tension=2e4,-1,abc")) == 2
    err = capsys.readouterr().err
    assert "2 of 3 variants invalid" in err
    assert "tension=-1: layers[0].tension = -1" in err
    assert "tension=abc: layers[0].tension = 'abc'" in err
    assert "tension=2e4:" not in err
    assert not out.exists()


@pytest.mark.parametrize(
    "vary, message",
    [
        ("layers[0].tension", "expected KEY=A,B[,C...]"),
        ("=1,2", "expected KEY=A,B[,C...]"),
        ("layers[0]..tension=1,2", "expected KEY=A,B[,C...]"),
        ("layers[0].tension=2e4", "expected two or more values"),
        ("layers[0].tension=2e4,,8e4", "an empty value"),
        ("layers[0].tension=2e4,", "an empty value"),
        ('layers[0]={model="wave-membrane",tension=1,{model="koiter-shell"}', "unbalanced '{'"),
        ('layers[0]={model="wave-membrane}', "unterminated string"),
        ("layers[0].tension=[1,2]],3", "unbalanced ']'"),
    ],
)
def test_bad_vary_syntax_exits_2_with_a_clear_message(tmp_path, capsys, vary, message):
    out = tmp_path / "cmp"
    assert main(compare_argv(out, MEMBRANE, vary=vary)) == 2
    err = capsys.readouterr().err
    assert "invalid command line" in err and "--vary" in err and message in err
    assert not out.exists()


def test_vary_values_split_like_set_values_inside_tables_and_strings():
    key, values = variants.parse_vary(f'layers[0]={WAVE}, {SHELL}')
    assert key == "layers[0]" and values == [WAVE, SHELL]
    _, values = variants.parse_vary('title="a, b",\'c,d\',"e\\",f"')
    assert values == ['"a, b"', "'c,d'", '"e\\",f"']


@pytest.mark.parametrize(
    "cases, vary, message",
    [
        ([MEMBRANE, MEMBRANE], "time.dt=1e-5,2e-5", "varies one case file; got 2"),
    ],
)
def test_vary_over_several_files_exits_2(tmp_path, capsys, cases, vary, message):
    assert main(compare_argv(tmp_path / "cmp", *cases, vary=vary)) == 2
    assert message in capsys.readouterr().err


def test_case_files_give_unique_labels_from_their_stems(tmp_path):
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "wall.toml").write_text(MEMBRANE.read_text())
    out = tmp_path / "cmp"
    code = main(compare_argv(out, tmp_path / "a" / "wall.toml", tmp_path / "b" / "wall.toml",
                             sets=["time.end=2e-4", "mesh.nz=4"]))
    assert code == 0
    report = json.loads((out / "report.json").read_text())
    assert [c["label"] for c in report["variants"]] == ["wall", "wall-2"]
    assert report["variants"][1]["probes"]["eta_mid"]["max_abs_diff"] == 0.0
    assert (out / "wall-2" / "summary.json").is_file()


def test_compare_works_with_one_case(tmp_path):
    """One case alone is a report of one column: its measurements and pictures."""
    out = tmp_path / "one"
    assert main(compare_argv(out, MEMBRANE)) == 0
    report = json.loads((out / "report.json").read_text())
    assert len(report["variants"]) == 1 and report["variants"][0]["status"] == "ok"
    assert (out / "probes.png").is_file() and (out / "eta_spacetime.png").is_file()


ARTERY = CASES / "pulse-artery-3layer.toml"  # intima (Koiter shell) | media (band) | lamina | adventitia (band)
LONG_PULSE = ["geometry.model=axisymmetric", "geometry.length=12", "mesh.nz=48", "mesh.nr=4", "time.end=0.028",
              "time.dt=2e-4", 'loads.inlet={model="cosine-pulse",amplitude=1.3333e4,duration=0.012}',
              ('output.probes=[{name="eta_2",quantity="eta",z=2.0},{name="eta_6",quantity="eta",z=6.0},'
               '{name="p_2",quantity="p",z=2.0,r=0.0},{name="p_6",quantity="p",z=6.0,r=0.0}]')]


def test_a_three_layer_tubes_pulse_wave_velocity_is_its_stacks_long_wave_speed(tmp_path):
    """The three-layer artery as a tube, a 12 ms pulse (its wavelength ≈ 10 R) along 12 cm: the clinician's speeds
    lie within 10 % of the long-wave speed of the whole stack, √(A/(ρ_f dA/dP)) = 394.8 cm/s (the intima's
    shell alone would give 133).  Measured: foot to foot 412.6 (η) and 412.5 (p) cm/s, +4.5 % (the foot rides
    on the pulse's shorter waves, which this wall carries faster); the ΔP–ΔA loop 387.7 and 388.6, −1.8 %."""
    out = tmp_path / "artery"
    assert main(compare_argv(out, ARTERY, sets=LONG_PULSE)) == 0
    (column,) = json.loads((out / "report.json").read_text())["variants"]
    stack = column["long_wave_speed"]
    assert stack == pytest.approx(394.8, abs=0.05)
    speeds = [column["pwv_foot_eta"], column["pwv_foot_p"], *(loop["value"] for loop in column["pwv_loop"])]
    assert len(speeds) == 4 and all(abs(s / stack - 1) < 0.10 for s in speeds), speeds
    table = md_table(out / "report.md")
    for title, cells in table.items():  # every speed of the report a positive number or a reason
        if "(cm/s)" in title:
            assert all(c.startswith("— (") or float(c) > 0 for c in cells), (title, cells)
