"""The Python API (multilayer.api, re-exported by multilayer): loading, running in memory and into a folder,
stepping, reading back — and that it gives the numbers of the command line, bit for bit."""

from __future__ import annotations

import ast
import math
import signal
from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_info

import multilayer as ml
from multilayer import api
from multilayer.case.keys import parse_value
from multilayer.commands.main import main
from multilayer.results.folder import ResultsError
from multilayer.runner import ledger
from multilayer.runner.loop import run_case

ROOT = Path(__file__).parents[1]
CASES = ROOT / "cases"
#: the composite pulse (pulse-koiter-thick) on a coarse mesh, 20 steps: fluid, a thin and a thick layer, every kind of probe
SMALL = {"mesh.nz": 16, "mesh.nr": 3, "time.end": 0.002}
#: a membrane pushed onto the axis: a wall-only run that fails at step 68
COLLAPSE = {"loads.interface": -3e4, "mesh.nz": 32}


def small_case(**more):
    return ml.load_case(CASES / "pulse-koiter-thick.toml", {**SMALL, **more})


def without_timings(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if k not in ("wall_time_s", "timings")}


def assert_same_results(a: ml.Results, b: ml.Results) -> None:
    assert list(a.series) == list(b.series)
    for column in a.series:
        assert np.array_equal(a.series[column], b.series[column], equal_nan=True), column
    assert list(a.probes) == list(b.probes)
    assert a.peaks == b.peaks
    assert without_timings(a.summary) == without_timings(b.summary)
    for field in ("eta_lumen", "wss_lumen"):
        x, y = getattr(a, field), getattr(b, field)
        assert (x is None) == (y is None), field
        if x is not None:
            assert all(np.array_equal(u, v) for u, v in zip(x, y)), field


# -- the package --------------------------------------------------------------------------------------------
def test_the_package_exports_the_api_and_its_version():
    from multilayer.version import __version__

    assert ml.__version__ == __version__
    assert set(ml.__all__) == {"ArgumentError", "Case", "CaseError", "Results", "ResultsError", "RunFailed", "Step",
                               "__version__", "load_case", "read_results", "run", "steps"}
    for name in ml.__all__:
        assert getattr(ml, name) is (getattr(api, name) if name != "__version__" else __version__)


def test_multilayer_run_is_the_function_and_the_time_loop_is_its_own_subpackage():
    import multilayer.runner.loop as loop

    assert ml.run is api.run and callable(ml.run)
    assert loop.__name__ == "multilayer.runner.loop" and callable(loop.run_case)


def _imports(path: Path) -> list[tuple[str, list[str]]]:
    """(module, names) of every import in ``path``, relative ones resolved, inside functions too."""
    package = list(path.relative_to(ROOT).parent.parts)
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [(alias.name, []) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else []
            module = ".".join([*base, *([node.module] if node.module else [])])
            out.append((module, [alias.name for alias in node.names]))
    return out


def test_nothing_below_the_package_imports_the_api_or_the_package_root():
    """The API is the top layer: only multilayer/__init__.py imports it, and no module imports the root
    package (``from multilayer import X``) — lower modules read the version from multilayer.version."""
    offenders = []
    for path in sorted([*(ROOT / "multilayer").rglob("*.py"), *(ROOT / "multilayer_plugins").rglob("*.py")]):
        if path == ROOT / "multilayer" / "__init__.py":
            continue
        for module, names in _imports(path):
            if module in ("multilayer", "multilayer.api"):
                offenders.append(f"{path.relative_to(ROOT)}: {module} {names}")
    assert offenders == []


# -- load_case ----------------------------------------------------------------------------------------------
def test_overrides_as_a_mapping_are_the_set_strings():
    layer = {"model": "wave-membrane", "density": 1.1, "thickness": 0.02, "tension": 2e5}
    mapping = ml.load_case(CASES / "pulse-koiter-thick.toml",
                           {"time.dt": np.float64(5e-5), "mesh.nz": np.int64(16), "mesh.nr": 3,
                            "title": 'a "quoted" title', "layers[0]": layer,
                            "coupler": {"model": "kinematic-splitting", "beta": 1}})
    strings = ml.load_case(CASES / "pulse-koiter-thick.toml",
                           ["time.dt=5e-5", "mesh.nz=16", "mesh.nr=3", r'title="a \"quoted\" title"',
                            'layers[0]={model="wave-membrane", density=1.1, thickness=0.02, tension=2e5}',
                            "coupler={ model = 'kinematic-splitting', beta = 1 }"])
    assert mapping.digest == strings.digest
    assert mapping.time.dt == 5e-5 and mapping.resolved["layers"][0]["model"] == "wave-membrane"
    assert mapping.title == 'a "quoted" title'


@pytest.mark.parametrize("value", [True, False, 0, -3, 1e-300, 5e-5, 1e16, 0.1, -2.5, math.inf, -math.inf, "",
                                   "none", "koiter-shell", 'q"u\\o\tte\n', "ünïcode", [1, 2.5, "x"],
                                   {"model": "m", "a.b": [1], "x y": {"z": False}}])
def test_a_mapping_value_reads_back_as_itself(value):
    assert parse_value(api._toml(value)) == value


def test_a_value_without_a_toml_form_is_a_case_error_at_its_key():
    with pytest.raises(ml.CaseError) as caught:
        ml.load_case(CASES / "membrane-mode.toml", {"time.dt": None, "layers[0].tension": object()})
    assert [p.path for p in caught.value.problems] == ["time.dt", "layers[0].tension"]
    assert "time.dt = None: cannot be written as a TOML value" in str(caught.value)


def test_a_bad_case_raises_case_error_with_every_key_path():
    with pytest.raises(ml.CaseError) as caught:
        ml.load_case(CASES / "pulse-koiter-thick.toml", {"layers[1].young": -3.0, "layers[0].modle": "x",
                                                         "time.dt": 0.0})
    paths = [p.path for p in caught.value.problems]
    assert {"layers[1].young", "layers[0].modle", "time.dt"} <= set(paths)
    assert "layers[1].young = -3.0: expected a number > 0.0" in str(caught.value)
    assert "did you mean 'model'?" in str(caught.value)
    with pytest.raises(ml.CaseError, match="no such case file"):
        ml.load_case(CASES / "no-such-case.toml")
    with pytest.raises(ml.CaseError, match=r"layers\[3\]: no such entry"):
        ml.load_case(CASES / "membrane-mode.toml", "layers[3].young=1")  # one string is one override


# -- run, steps, read_results -------------------------------------------------------------------------------
def test_a_run_in_memory_is_the_run_into_a_folder_bit_for_bit(tmp_path):
    case = small_case()
    held = ml.run(case)
    assert held.folder is None and held.ok and held.steps == 20 and len(held.t) == 20
    assert not list(tmp_path.iterdir())
    saved = ml.run(case, tmp_path / "run")
    assert saved.folder == tmp_path / "run"
    assert_same_results(held, saved)
    assert held.max_relative_residual < 1e-12
    assert set(held.probes) == {p.name for p in case.output.probes}
    z, t, eta = held.eta_lumen  # (steps, the lumen's nz + 1 vertices)
    assert eta.shape == (20, 16 + 1) and np.all(np.diff(z) > 0) and np.array_equal(t, held.t)
    # the peaks the command line prints (the run loop's tally) are the Results' peaks
    printed = run_case(case, tmp_path / "again").peaks
    assert printed == held.peaks and set(printed) == {f"eta_z{k}" for k in range(1, 6)}
    # and read_results reads what multilayer run writes
    assert main(["run", str(CASES / "pulse-koiter-thick.toml"), "--out", str(tmp_path / "cli"), "--quiet",
                 "--no-plots", *(f"--set={k}={v}" for k, v in SMALL.items())]) == 0
    assert_same_results(held, ml.read_results(tmp_path / "cli"))


def test_the_examples_of_the_api_docstrings(monkeypatch):
    """The lines of load_case's, run's and steps' docstrings (examples there, not doctests: they need the installed
    plugins, which the core's doctests never use), run from the checkout as they are written."""
    monkeypatch.chdir(CASES.parent)
    case = ml.load_case("cases/membrane-mode.toml", {"time.end": 0.001, "mesh.nz": 16})
    assert (case.time.steps, case.mesh.nz) == (50, 16)
    with pytest.raises(ml.CaseError, match=r"^layers\[0\].tension = -1: expected a number >= 0.0 \(dyn/cm\) \(from --set\)$"):
        ml.load_case("cases/membrane-mode.toml", ["layers[0].tension=-1"])
    res = ml.run(case)
    assert (res.status, len(res.t), res.max_relative_residual < 1e-12) == ("ok", 50, True)
    case = ml.load_case("cases/membrane-mode.toml", {"mesh.nz": 16})
    for step in ml.steps(case):
        if step.probes["eta_mid"] < 0.005:
            break
    assert (step.n, round(step.t, 5), step.ledger["energy.relative_residual"] < 1e-12) == (235, 0.0047, True)


def test_steps_are_the_rows_of_a_run_and_carry_the_state():
    case = small_case()
    held = ml.run(case)
    rows = list(ml.steps(case))
    assert [s.n for s in rows] == list(range(1, 21))
    for column in held.series:
        assert np.array_equal([s.row.get(column, np.nan) for s in rows], held.series[column], equal_nan=True)
    last = rows[-1]
    assert last.t == held.t[-1] and last.state.t == last.t and last.state.n == 20
    assert {"energy.total", "energy.residual", "energy.relative_residual"} <= set(last.ledger)
    assert all(isinstance(v, float) for v in last.ledger.values())
    assert any(k.startswith("work.") for k in last.ledger) and any(k.startswith("dissipation.") for k in last.ledger)
    assert last.probes == {name: last.row[name] for name in held.probes}
    assert last.state.wall.d.shape == last.state.wall.V.shape


def test_steps_closed_early_stops_the_run_and_leaves_nothing_behind(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    closes, made = [], []
    original_close, original_iterate = ledger.close, api.iterate_steps

    def counting_close(*args):  # one ledger per step computed
        closes.append(1)
        return original_close(*args)

    def recording_iterate(*args, **kwargs):  # the stepping generator the API drives
        made.append(original_iterate(*args, **kwargs))
        return made[-1]

    monkeypatch.setattr(ledger, "close", counting_close)
    monkeypatch.setattr(api, "iterate_steps", recording_iterate)
    threads_before = [lib["num_threads"] for lib in threadpool_info()]
    handlers_before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    case = ml.load_case(CASES / "pulse-koiter-thick.toml", {**SMALL, "output.every": 1})  # snapshots: none made
    gen = ml.steps(case)
    for step in gen:
        assert [lib["num_threads"] for lib in threadpool_info()] == threads_before  # no limit between steps
        if step.n == 3:
            break
    gen.close()
    assert len(closes) == 3  # no step computed beyond the last one asked for
    assert gen.gi_frame is None and made[0].gi_frame is None  # the API's generator and the stepping's: closed
    assert next(gen, None) is None
    assert not list(tmp_path.iterdir())
    assert [lib["num_threads"] for lib in threadpool_info()] == threads_before
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == handlers_before


def test_a_guard_in_steps_raises_run_failed_naming_the_time():
    case = ml.load_case(CASES / "membrane-mode.toml", COLLAPSE)
    done = []
    with pytest.raises(ml.RunFailed, match=r"wall collapse \(inward\) at t = 0\.00136 s, z = "):
        for step in ml.steps(case):
            done.append(step.n)
    assert done == list(range(1, 68))


def test_read_results_of_a_failed_run(tmp_path):
    case = ml.load_case(CASES / "membrane-mode.toml", COLLAPSE)
    folder = tmp_path / "collapse"
    res = ml.run(case, folder)
    back = ml.read_results(folder)
    for r in (res, back):
        assert r.status == "failed" and not r.ok
        assert "collapse" in r.reason and "t = 0.00136 s" in r.reason
        assert r.steps == len(r.t) == 67 and np.all(np.isfinite(r.series["eta_mid"]))
        assert r.eta_lumen is not None and r.eta_lumen[2].shape[0] == 67
    assert_same_results(res, back)
    assert_same_results(res, ml.run(case))  # in memory: the same failure, the same rows
    assert repr(back).startswith("Results(status='failed', steps=67, t_end=0.00134")


def test_a_run_that_breaks_the_energy_bound_keeps_that_row_in_memory_and_on_disk(tmp_path):
    case = ml.load_case(CASES / "pulse-membrane.toml",
                        {"coupler": "dirichlet-neumann-explicit", "mesh.nz": 16, "mesh.nr": 3})
    held, saved = ml.run(case), ml.run(case, tmp_path / "dn")
    assert held.status == "failed" and "energy grew beyond the work put in at t = 0.0001 s" in held.reason
    assert held.steps == len(held.t) == 1
    assert_same_results(held, saved)
    with pytest.raises(ml.RunFailed, match="energy grew beyond the work put in at t = 0.0001 s"):
        list(ml.steps(case))


def test_read_results_of_a_folder_that_is_none(tmp_path):
    with pytest.raises(FileNotFoundError, match="not a results folder"):
        ml.read_results(tmp_path)
    with pytest.raises(FileNotFoundError):
        ml.read_results(tmp_path / "missing")


def test_run_options(tmp_path, capsys):
    case = ml.load_case(CASES / "membrane-mode.toml", {"time.end": 0.0004, "mesh.nz": 8})
    with pytest.raises(ValueError, match="need a results folder"):
        ml.run(case, checkpoint_every=5)
    with pytest.raises(ValueError, match="need a results folder"):
        ml.run(case, plots=True)
    rows = []
    res = ml.run(case, tmp_path / "cp", checkpoint_every=10, progress=rows.append, plots=True)
    assert res.ok and [r["step"] for r in rows] == list(range(1, 21)) and rows[-1]["t"] == res.t[-1]
    assert {"checkpoint.json", "checkpoint.npz", "probes.png", "energy.png"} <= {p.name for p in (tmp_path / "cp").iterdir()}
    assert ml.run(case, progress=True).ok
    assert "step" in capsys.readouterr().err  # the progress bar


def test_run_into_a_foreign_folder_needs_force(tmp_path):
    """As ``multilayer run --force``: refused without it, and with it the user's file is left alone."""
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "notes.txt").write_text("my notes")
    case = small_case()
    with pytest.raises(ResultsError, match="not a results folder"):
        ml.run(case, folder)
    res = ml.run(case, folder, force=True)
    assert res.ok and (folder / "notes.txt").read_text() == "my notes"
    with pytest.raises(ValueError, match="need a results folder"):
        ml.run(case, force=True)


@pytest.mark.parametrize("call, words", [
    (lambda ml, case: ml.run(str(CASES / "membrane-mode.toml")), "run(case=...): expected a Case, got the path"),
    (lambda ml, case: ml.run(case, checkpoint_every="5"), "run(checkpoint_every=...): expected a whole number"),
    (lambda ml, case: ml.run(case, checkpoint_every=-1), "run(checkpoint_every=...)"),
    (lambda ml, case: ml.run(case, out=3), "run(out=...): expected a path"),
    (lambda ml, case: ml.run(case, plots="yes"), "run(plots=...): expected True or False"),
    (lambda ml, case: ml.run(case, progress=3), "run(progress=...)"),
    (lambda ml, case: ml.load_case(CASES / "membrane-mode.toml", 5), "load_case(overrides=...)"),
    (lambda ml, case: ml.load_case(CASES / "membrane-mode.toml", [5]), "load_case(overrides=...)"),
    (lambda ml, case: ml.load_case(7), "load_case(path=...): expected a path"),
    (lambda ml, case: ml.read_results(3), "read_results(folder=...): expected a path"),
    (lambda ml, case: next(ml.steps("case.toml")), "steps(case=...): expected a Case, got the path"),
])
def test_the_api_names_a_wrong_argument_instead_of_failing_inside(call, words):
    """Issue 36: a wrong type or value gets a multilayer error naming the argument and what was expected."""
    import multilayer as ml

    case = ml.load_case(CASES / "membrane-mode.toml", {"time.end": 0.001, "mesh.nz": 16})
    with pytest.raises(ml.ArgumentError) as info:
        call(ml, case)
    assert words in str(info.value)
    assert isinstance(info.value, TypeError) and isinstance(info.value, ValueError)  # either except clause catches it
