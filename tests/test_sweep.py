"""``multilayer sweep``: the [sweep] table, planning by digest, idempotent re-submission, Dask with a dying worker."""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import scipy.sparse as sp

from multilayer.campaign import executor, sweep
from multilayer.case import grid
from multilayer.case.casefile import load_case
from multilayer.commands.main import main
from multilayer.numerics import linsolve
from multilayer.plugin.registry import Registry

CASES = Path(__file__).parents[1] / "cases"
PULSE = CASES / "pulse-koiter.toml"
SMALL = ("mesh.nz=12", "mesh.nr=3", "time.end=0.002")
GRID = '[sweep]\ngrid = { "time.dt" = [1e-4, 5e-5], "layers[0].young" = [5e5, 1e6] }\n\n'
#: the wall alone (no fluid): a run takes a fraction of a second
MEMBRANE = CASES / "membrane-mode.toml"


def with_sweep(tmp_path: Path, table: str, case: Path = PULSE) -> Path:
    """``case`` with ``table`` put before its first section."""
    text = case.read_text()
    first = text.index("\n[") + 1
    path = tmp_path / case.name
    path.write_text(text[:first] + table + text[first:])
    return path


def sets(*overrides: str) -> list[str]:
    return [a for o in overrides for a in ("--set", o)]


def rows(out: Path) -> list[dict[str, str]]:
    with open(out / "sweep.csv", newline="") as f:
        return list(csv.DictReader(f))


# -- the [sweep] table -------------------------------------------------------------


@pytest.mark.parametrize("table, messages", [
    ('[sweep]\ngird = { "time.dt" = [1e-4] }\n', ["sweep.gird", "unknown key", "did you mean 'grid'?"]),
    ('[sweep]\ngrid = { "time.dt" = 1e-4 }\n', ['sweep.grid."time.dt" = 0.0001: expected a list']),
    ('[sweep]\ngrid = { "time.dt" = [] }\n', ['sweep.grid."time.dt" = []: expected one or more values']),
    ('[sweep]\ngrid = { "time dt" = [1e-4, 2e-4] }\n', ['sweep.grid."time dt"', "not a key path"]),
    ('[sweep]\nzip = { "time.dt" = [1e-4, 5e-5], "time.end" = [1e-3] }\n', ["sweep.zip", "got 2, 1"]),
    ('[sweep]\ngrid = { "time.dt" = [1e-4] }\nzip = { "time.dt" = [1e-4] }\n', ["'time.dt'", "varied twice"]),
    ("[sweep]\n", ["sweep = {}: varies no key"]),
    ('sweep = 3\n', ["sweep = 3: expected a table"]),
])
def test_a_bad_sweep_table_is_an_invalid_case_naming_the_key_path(tmp_path, capsys, table, messages):
    case = with_sweep(tmp_path, table)
    for argv in (["validate", str(case)], ["run", str(case), "--out", str(tmp_path / "r")],
                 ["sweep", str(case), "--out", str(tmp_path / "s"), "--jobs", "1"]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert all(m in err for m in messages), err
        assert "Traceback" not in err
    assert not (tmp_path / "r").exists() and not (tmp_path / "s" / "runs").exists()


def test_validate_says_it_is_a_sweep_and_run_ignores_the_table(tmp_path, capsys):
    case = with_sweep(tmp_path, GRID)
    assert main(["validate", str(case)]) == 0
    assert "sweep    4 runs over time.dt, layers[0].young" in capsys.readouterr().out
    # the table is no part of the case: the same digest as the file without it
    assert load_case(case).digest == load_case(PULSE).digest


def test_toml_text_reads_back_to_the_same_value():
    from multilayer.case.keys import parse_value

    for value in (5e-5, 1e6, 3, -2.5, "koiter-shell", 'a "b"', True, [1, 2.5],
                  {"model": "wave-membrane", "tension": 2e4, "x y": [1, {"a": 1}]}):
        assert parse_value(grid.toml_text(value)) == value


# -- planning ------------------------------------------------------------------------


def test_the_grid_expands_into_validated_cases_with_the_digests_of_explicit_overrides(tmp_path):
    case = with_sweep(tmp_path, GRID)
    registry = Registry.load()
    runs, invalid = sweep.plan(case, sweep.sweep_axes(sweep.read_sweep_table(case), []), SMALL, registry)
    assert not invalid
    assert [r.values for r in runs] == [
        (("time.dt", "0.0001"), ("layers[0].young", "500000.0")), (("time.dt", "0.0001"), ("layers[0].young", "1000000.0")),
        (("time.dt", "5e-05"), ("layers[0].young", "500000.0")), (("time.dt", "5e-05"), ("layers[0].young", "1000000.0"))]
    for run in runs:
        explicit = load_case(PULSE, [*SMALL, *(f"{k}={v}" for k, v in run.values)], registry)
        assert run.digest == explicit.digest
        assert run.folder == f"runs/{explicit.digest[:12]}"
    assert len({r.digest for r in runs}) == 4


def test_zip_varies_keys_together_and_vary_replaces_or_adds_an_axis(tmp_path):
    table = ('[sweep]\ngrid = { "time.dt" = [1e-4, 5e-5] }\n'
             'zip = { "layers[0].young" = [5e5, 1e6], "layers[0].thickness" = [0.1, 0.2] }\n\n')
    case = with_sweep(tmp_path, table)
    parsed = sweep.read_sweep_table(case)
    assert parsed.size == 4
    axes = sweep.sweep_axes(parsed, ["time.dt=2e-4,1e-4,5e-5", "mesh.nz=12,24"])
    points = grid.combinations(axes)
    assert len(points) == 3 * 2 * 2
    assert {tuple(s.override for s in p if s.key.startswith("layers")) for p in points} == {
        ("layers[0].young=500000.0", "layers[0].thickness=0.1"), ("layers[0].young=1000000.0", "layers[0].thickness=0.2")}
    with pytest.raises(sweep.CaseError, match="varied together with others in"):
        sweep.sweep_axes(parsed, ["layers[0].young=1,2"])
    with pytest.raises(sweep.CaseError, match="nothing to sweep"):
        sweep.sweep_axes(None, [])


def test_a_whole_inline_table_can_be_swept_and_equal_cases_are_planned_once(tmp_path):
    table = ('[sweep]\ngrid = { "layers[0]" = [{model = "wave-membrane", density = 1.1, thickness = 0.1, '
             'tension = 2e5}, {model = "koiter-shell", density = 1.1, thickness = 0.1, young = 7.5e5, '
             'poisson = 0.49}], "time.dt" = [1e-4, 0.0001] }\n\n')
    case = with_sweep(tmp_path, table)
    runs, invalid = sweep.plan(case, sweep.sweep_axes(sweep.read_sweep_table(case), []), SMALL, Registry.load())
    assert not invalid
    assert len(runs) == 2  # 1e-4 and 0.0001 are one case
    assert [dict(r.values)["layers[0]"].split(",")[0] for r in runs] == ['{model = "wave-membrane"',
                                                                         '{model = "koiter-shell"']


def test_an_invalid_swept_value_exits_2_naming_the_run_and_the_key_and_nothing_runs(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["sweep", str(PULSE), "--out", str(out), "--jobs", "1", "--vary", "time.dt=1e-4,-1",
                 "--vary", "layers[0].poisson=0.3,0.7", *sets(*SMALL)])
    err = capsys.readouterr().err
    assert code == 2
    assert "sweep: 3 of 4 runs invalid" in err
    assert "time.dt=-1, layers[0].poisson=0.3: time.dt = -1" in err
    assert "layers[0].poisson = 0.7" in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize("extra, message", [
    (["--jobs", "0"], "--jobs = 0: expected an integer >= 1"),
    (["--vary", "time.dt"], "--vary = 'time.dt': expected KEY=A,B"),
    (["--vary", "time.dt=1e-4,5e-5", "--vary", "time.dt=1,2"], "time.dt is already varied"),
    (["--vary", "time.dtt=1e-4,5e-5"], "time.dtt = 0.0001: unknown key; did you mean 'dt'?"),
    (["--vary", "layers[3].young=1,2"], "layers[3]: no such entry; 'layers' has 1"),
])
def test_bad_command_lines_exit_2(tmp_path, capsys, extra, message):
    assert main(["sweep", str(PULSE), "--out", str(tmp_path / "o"), *extra]) == 2
    assert message in capsys.readouterr().err


# -- running here, collecting, re-submitting ---------------------------------------------


def test_a_serial_sweep_collects_every_run_and_a_resubmission_reruns_only_what_is_not_ok(tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["sweep", str(MEMBRANE), "--out", str(out), "--jobs", "1", "--vary", "layers[0].tension=2e4,8e4",
            "--vary", "time.dt=2e-5,1e-5"]
    assert main(argv) == 0
    table = rows(out)
    assert len(table) == 4 and {r["status"] for r in table} == {"ok"}
    assert list(table[0])[:3] == ["digest", "layers[0].tension", "time.dt"]
    for column in ("wall_time_s", "dofs", "max_relative_residual", "wave_speed", "folder"):
        assert column in table[0]
    peaks = [c for c in table[0] if c.startswith("peak_eta.")]
    assert peaks and all(float(r[peaks[0]]) > 0 for r in table)
    assert float(table[0]["dofs"]) > 0 and float(table[0]["max_relative_residual"]) < 1e-8
    for r in table:
        summary = json.loads((out / r["folder"] / "summary.json").read_text())
        assert summary["case_hash"].startswith(r["digest"]) and r["folder"] == f"runs/{r['digest']}"
    plan = json.loads((out / "plan.json").read_text())
    assert [p["values"] for p in plan["runs"]][1] == {"layers[0].tension": "2e4", "time.dt": "1e-5"}
    assert (out / "sweep_layers_0_.tension.png").is_file() and (out / "sweep_time.dt.png").is_file()
    assert "| digest |" in (out / "sweep.md").read_text()
    capsys.readouterr()

    stamps = {r["folder"]: (out / r["folder"] / "summary.json").stat().st_mtime_ns for r in table}
    assert main(argv) == 0
    assert "4 runs, 4 already done, nothing to run" in capsys.readouterr().err
    assert stamps == {f: (out / f / "summary.json").stat().st_mtime_ns for f in stamps}

    # a failed run, a run its worker never finished and a folder of another case are run again; the rest not
    first, second, third, fourth = (out / r["folder"] / "summary.json" for r in table)
    first.write_text(json.dumps({**json.loads(first.read_text()), "status": "failed"}))
    second.write_text(json.dumps({"status": "running", "pid": 1}))
    third.write_text(json.dumps({**json.loads(third.read_text()), "case_hash": "0" * 64}))
    assert main(argv) == 0
    assert "4 runs, 1 already done, 3 to run on this process" in capsys.readouterr().err
    assert fourth.stat().st_mtime_ns == stamps[table[3]["folder"]]
    assert {r["status"] for r in rows(out)} == {"ok"}


def test_the_pardiso_style_backends_belong_to_a_solver_not_to_the_process():
    a, b = linsolve.SolverStats(), linsolve.SolverStats()
    matrix = sp.eye(3).tocsc() * 2.0
    linsolve.factorize(matrix, a)
    linsolve.factorize(matrix, a)
    linsolve.factorize(matrix, b)
    assert a.backends["superlu"] is not b.backends["superlu"]
    assert len(a.backends) == 1 and a.factorizations == 2
    assert all(isinstance(cls, type) for _, cls in linsolve.OPTIONAL.values())  # classes, no shared instance


def test_a_plugin_file_travels_as_its_source(tmp_path):
    path = tmp_path / "tiny_plugin.py"
    path.write_text("VALUE = 41 + 1\n")
    shipped = executor.ship_plugins([str(path)])
    path.unlink()  # a worker elsewhere has no such file
    module = shipped[0].load()
    assert module.VALUE == 42 and module.__name__ == "tiny_plugin"
    assert executor.Plugin.ship("some.module").source is None
    with pytest.raises(executor.RegistryError, match="cannot read it"):
        executor.Plugin.ship(str(path))


# -- Dask -----------------------------------------------------------------------------

dask = pytest.mark.skipif(not executor.dask_installed(), reason="dask.distributed not installed (extra 'dask')")


def _kill_a_run_in_flight(out: Path, deadline: float) -> tuple[Path, int]:
    """SIGKILL the worker process holding the first run seen in flight: (its folder, the PID killed)."""
    while time.monotonic() < deadline:
        for summary in sorted(out.glob("runs/*/summary.json")):
            try:
                placeholder = json.loads(summary.read_text())
            except ValueError:
                continue
            if placeholder.get("status") == "running" and (summary.parent / "series.csv").is_file():
                os.kill(placeholder["pid"], signal.SIGKILL)
                return summary.parent, placeholder["pid"]
        time.sleep(0.01)
    raise AssertionError("no run was seen in flight")


@dask
def test_a_sweep_on_two_local_dask_workers_survives_a_worker_killed_mid_run(tmp_path, capsys):
    case = with_sweep(tmp_path, GRID)
    out = tmp_path / "out"
    argv = ["sweep", str(case), "--out", str(out), "--jobs", "2", *sets(*SMALL)]
    process = subprocess.Popen([sys.executable, "-m", "multilayer.commands", *argv], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    try:
        folder, pid = _kill_a_run_in_flight(out, time.monotonic() + 60)
        stdout, stderr = process.communicate(timeout=90)
    finally:
        process.kill()
    assert process.returncode == 0, stderr
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)  # the worker that held the run is gone ...
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["steps"] > 0  # ... so another process ran it again, to its end
    assert "local Dask cluster of 2 worker(s)" in stderr
    table = rows(out)
    assert len(table) == 4 and {r["status"] for r in table} == {"ok"}
    assert len({r["digest"] for r in table}) == 4

    stamps = {r["folder"]: (out / r["folder"] / "summary.json").stat().st_mtime_ns for r in table}
    assert main(argv) == 0  # re-submitted: nothing new runs
    assert "4 runs, 4 already done, nothing to run" in capsys.readouterr().err
    assert stamps == {f: (out / f / "summary.json").stat().st_mtime_ns for f in stamps}


# -- the executor without Dask ----------------------------------------------------------


def test_without_dask_several_jobs_run_in_a_process_pool_and_a_scheduler_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(executor, "dask_installed", lambda: False)
    assert executor.how(2) == "processes" and executor.how(1) == "serial"
    jobs = [executor.Job(f"t{t}", MEMBRANE, (f"layers[0].tension={t}",), tmp_path / f"t{t}") for t in (2e4, 8e4)]
    lines = []
    status = executor.execute(jobs, 2, Registry.load(), log=lines.append)
    assert status == {"t20000.0": ("ok", ""), "t80000.0": ("ok", "")}
    assert len(lines) == 2 and lines[-1].endswith("running 0, queued 0, failed 0")
    for job in jobs:
        assert json.loads((job.folder / "summary.json").read_text())["status"] == "ok"
    with pytest.raises(executor.ExecutorError, match=r"pip install 'multilayer\[dask\]'"):
        executor.execute(jobs, 1, Registry.load(), scheduler="tcp://127.0.0.1:1")
    assert main(["sweep", str(MEMBRANE), "--out", str(tmp_path / "s"), "--vary", "time.dt=2e-5,1e-5",
                 "--scheduler", "tcp://127.0.0.1:1"]) == 2


@dask
def test_a_local_dask_cluster_runs_the_jobs_and_leaves_this_process_environment_as_it_was(tmp_path):
    before = dict(os.environ)
    jobs = [executor.Job(f"t{t}", MEMBRANE, (f"layers[0].tension={t}",), tmp_path / f"t{t}") for t in (2e4, 8e4)]
    lines = []
    assert executor.execute(jobs, 2, Registry.load(), log=lines.append) == {"t20000.0": ("ok", ""),
                                                                            "t80000.0": ("ok", "")}
    assert dict(os.environ) == before  # Dask's nanny sets OMP_NUM_THREADS=1 and more in it while it runs
    assert len(lines) == 2
