"""Runs that fail stop cleanly, say where and when, and keep what was written."""

import csv
import json
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from multilayer.cli import main
from multilayer.hookspecs import hookimpl
from multilayer.interfaces import LayerMatrices, ThinLayer
from multilayer.records import LayerPlugin, Param

CASES = Path(__file__).parents[1] / "cases"


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
    """A layer whose stiffness is NaN: every value it touches goes non-finite."""

    def forms(self, space):
        n = space.ndofs
        K = sp.identity(n, format="csr") * np.nan
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
    assert "layers[0]" in summary["reason"] and "non-finite" in summary["reason"]


def test_non_finite_state_stops_the_run_with_time(tmp_path):
    out = tmp_path / "nan-load"
    # a load that turns NaN at t > 1e-4 (sqrt of a negative number)
    code = main(["run", str(CASES / "membrane-mode.toml"), "--out", str(out),
                 "--set", 'loads.interface="100*sqrt(1e-4 - t)"'])
    assert code == 1
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and "non-finite" in summary["reason"]
    assert "t = 0.00012" in summary["reason"]
    rows = list(csv.DictReader(open(out / "series.csv")))
    assert len(rows) == 5  # steps up to t = 1e-4 were fine and are kept
