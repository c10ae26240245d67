"""Runs that fail stop cleanly, say where and when, and keep what was written."""

import csv
import json
from pathlib import Path

import attrs
import numpy as np
import pytest
import scipy.sparse as sp

from multilayer.case.casefile import load_case
from multilayer.commands.main import main
from multilayer.functions.formula import Formula
from multilayer.functions.loads import FormulaPressure
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import LayerPlugin, Param
from multilayer.runner.loop import run_case
from multilayer.wall.layer import LayerMatrices, ThinLayer

CASES = Path(__file__).parents[1] / "cases"


def membrane_with_load(expr: str, *sets: str):
    """membrane-mode.toml with the interface load ``expr``, set after validation.

    Validation refuses a formula that is not finite on [0, T]; a run must
    still stop cleanly when a load (or anything else) goes non-finite, so
    the load is put in place the way a plugin or a script could.
    """
    case = load_case(CASES / "membrane-mode.toml", sets)
    load = FormulaPressure(Formula.parse(expr, variables=("t",)))
    return attrs.evolve(case, loads=attrs.evolve(case.loads, interface=load))


def test_wall_collapse_stops_the_run_and_keeps_results(tmp_path):
    out = tmp_path / "collapse"
    code = main(["run", str(CASES / "membrane-mode.toml"), "--out", str(out),
                 "--set", "loads.interface=-3e4", "--set", "output.every=20"])
    assert code == 1
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed"
    assert "collapse" in summary["reason"] and "t = " in summary["reason"] and "z = " in summary["reason"]
    rows = list(csv.DictReader(open(out / "series.csv")))
    assert 0 < len(rows) == summary["steps"]
    assert float(rows[-1]["eta_mid"]) < 0
    assert (out / "wall.pvd").exists() and len(list(out.glob("wall_*.vtu"))) >= 2


class Broken(ThinLayer):
    """A layer whose stiffness is NaN on a fine mesh: validation's small wall cannot see it, the run does."""

    def forms(self, space):
        n = space.ndofs
        K = sp.identity(n, format="csr") * (np.nan if n > 16 else 1.0)
        return LayerMatrices(sp.identity(n, format="csr"), sp.csr_matrix((n, n)), K)


@hookimpl
def multilayer_layers():
    return [LayerPlugin(name="broken", factory=lambda density: Broken(), thin=True,
                        params=(Param("density", doc="unused"),), doc="Goes NaN.")]


def test_a_plugin_with_non_finite_matrices_is_named(tmp_path):
    case = tmp_path / "nan.toml"
    text = (CASES / "membrane-mode.toml").read_text()
    case.write_text(text.replace('model = "wave-membrane"', 'model = "broken"')
                    .replace("thickness = 0.1   # cm\ntension = 2.0e4   # C1, dyn/cm\n", ""))
    out = tmp_path / "nan"
    code = main(["run", str(case), "--out", str(out), "--plugin", __name__])
    assert code == 1
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed"
    assert "layers[0] (broken): stiffness has non-finite entries" in summary["reason"]


@pytest.mark.filterwarnings("ignore:invalid value encountered in sqrt")  # the load is NaN on purpose
def test_non_finite_state_stops_the_run_with_time(tmp_path):
    out = tmp_path / "nan-load"
    # a load that turns NaN at t > 1e-4 (sqrt of a negative number)
    result = run_case(membrane_with_load("100*sqrt(1e-4 - t)"), out)
    assert result.status == "failed"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and "non-finite" in summary["reason"]
    assert "t = 0.00012" in summary["reason"]
    rows = list(csv.DictReader(open(out / "series.csv")))
    assert len(rows) == 5  # steps up to t = 1e-4 were fine and are kept


@pytest.mark.filterwarnings("ignore:invalid value encountered in sqrt")  # the load is NaN on purpose
def test_a_rerun_into_the_same_folder_leaves_no_stale_results(tmp_path):
    out = tmp_path / "again"
    assert main(["run", str(CASES / "membrane-mode.toml"), "--out", str(out), "--set", "output.every=100"]) == 0
    assert len(list(out.glob("wall_*.vtu"))) == 11
    # the second run fails at its first step: nothing of the first may remain
    assert run_case(membrane_with_load("sqrt(-1-t)", "output.every=100"), out).status == "failed"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["steps"] == 0
    assert len((out / "series.csv").read_text().splitlines()) == 1  # the new run's header, no stale row
    # only the new run's own t = 0 snapshot
    assert [p.name for p in out.glob("wall_*.vtu")] == ["wall_000000.vtu"]
    assert (out / "wall.pvd").read_text().count("<DataSet") == 1


SUMMARY_KEYS = {"status", "reason", "case", "case_hash", "plugins", "dofs", "steps", "wall_time_s",
                "timings", "energy"}


def test_a_crash_inside_a_coupler_still_writes_the_summary(tmp_path, monkeypatch, capsys):
    import multilayer_plugins.structure_only as so

    def crash(self, setup, state):
        yield from ()
        raise KeyError("a bug in a coupler")

    monkeypatch.setattr(so.StructureOnly, "evolve", crash)
    out = tmp_path / "crash"
    assert main(["run", str(CASES / "membrane-mode.toml"), "--out", str(out)]) == 1
    summary = json.loads((out / "summary.json").read_text())
    assert SUMMARY_KEYS <= set(summary)
    assert summary["status"] == "failed" and "KeyError" in summary["reason"]
    assert "a bug in a coupler" in summary["traceback"]
    assert {"assembly", "factorization", "solves", "output"} <= set(summary["timings"])
    assert "Traceback" in capsys.readouterr().err  # a bug: the traceback is shown for the report


def test_summary_of_a_good_run_has_every_contract_key(tmp_path):
    out = tmp_path / "ok"
    assert main(["run", str(CASES / "membrane-mode.toml"), "--out", str(out), "--set", "time.end=1e-4"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert SUMMARY_KEYS <= set(summary) and summary["reason"] == ""


def test_out_pointing_at_a_file_is_a_usage_error(tmp_path, capsys):
    target = tmp_path / "a-file"
    target.write_text("not a folder")
    assert main(["run", str(CASES / "membrane-mode.toml"), "--out", str(target)]) == 2
    assert "is a file, not a folder" in capsys.readouterr().err
    assert target.read_text() == "not a folder"
