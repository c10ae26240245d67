"""A geometry from a test-local plugin: the planar channel of depth d, with no edit in multilayer/.

Its measure is d times the planar one, so every integral of the scene —
mass, stiffness, the fluid's forms, the end loads, the lumen's unit load —
scales by d, and the motion does not change at all: η and the velocities
are those of the planar run (to round-off), while every energy, work,
dissipation and flow rate is d times the planar one, and the ledger closes.
If anything in the core integrated with the planar measure behind the
geometry's back, the motion would change or a term would not scale.
"""

import sys

import numpy as np
import pytest
from runs import CASES

from multilayer.case.casefile import load_case
from multilayer.geometry.contract import Geometry
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.problems import CaseError
from multilayer.plugin.records import GeometryPlugin, Param
from multilayer.plugin.registry import Registry
from multilayer.results.reading import read_run
from multilayer.runner.loop import run_case


class Deep(Geometry):
    """A planar channel of depth ``depth``: weight(r) = depth."""

    name = "test-deep"

    def __init__(self, depth: float):
        self.depth = depth

    def weight(self, r):
        return np.full(np.shape(r), self.depth)


@hookimpl
def multilayer_geometries():
    return [GeometryPlugin(name="test-deep", factory=Deep,
                           params=(Param("depth", "d", "cm", gt=0.0, doc="depth of the channel"),),
                           doc="The planar channel of a given depth (a test's own plugin).")]


REGISTRY = Registry.load(extra=[sys.modules[__name__]])
DEPTH = 3.0
TINY = ("geometry.length=2.0", "mesh.nz=8", "mesh.nr=2", "time.end=0.002",
        'output.probes=[{ name = "eta_z1", quantity = "eta", z = 1.0 }, '
        '{ name = "q_in", quantity = "flow_rate", z = 0.0 }, { name = "p_z1", quantity = "p", z = 1.0, r = 0.0 }]')


def both(tmp_path, case, *sets):
    runs = []
    for name, geometry in (("planar", ()), ("deep", ('geometry.model="test-deep"', f"geometry.depth={DEPTH}"))):
        case_ = load_case(CASES / f"{case}.toml", [*sets, *geometry], REGISTRY)
        result = run_case(case_, tmp_path / name, REGISTRY)
        assert result.status == "ok", result.reason
        runs.append(read_run(name, tmp_path / name))
    return runs


def scaled_columns(series):
    return [k for k in series if k.split(".")[0] in ("kinetic", "elastic", "work", "dissipation", "energy")
            and k not in ("energy.residual", "energy.relative_residual")]


@pytest.mark.parametrize("case, sets", [
    ("pulse-koiter-thick", (*TINY, "layers[1].cells=2")),
    ("pulse-koiter", (*TINY, 'coupler={model="monolithic",scheme="crank-nicolson"}')),
    ("pulse-membrane", (*TINY, 'coupler={model="dirichlet-neumann-implicit",tolerance=1e-11}')),
    ("poiseuille-rigid", ("time.dt=1000.0", "time.end=3000.0")),
])
def test_a_deeper_channel_moves_alike_and_every_integral_scales_with_its_depth(tmp_path, case, sets):
    planar, deep = both(tmp_path, case, *sets)
    p, d = planar.series, deep.series
    motion = [k for k in p if k.startswith(("eta", "p_", "uz"))]
    for k in motion:  # the motion and the pressure do not see the depth
        assert np.allclose(d[k], p[k], rtol=1e-9, atol=1e-12 * np.max(np.abs(p[k]))), k
    columns = scaled_columns(p)
    assert {"energy.total", "kinetic.fluid"} <= set(columns) and any(k.startswith("work.") for k in columns)
    # energies, work, dissipation: depth times the planar ones (to round-off of the run's energy scale: some
    # terms, like the splitting's geometric remainder, are round-off themselves)
    scale = max(np.max(np.abs(p[k])) for k in columns)
    for k in columns:
        assert np.allclose(d[k], DEPTH * p[k], rtol=1e-9, atol=1e-11 * DEPTH * scale), k
    for k in (k for k in p if k.startswith("q_")):  # flow rates too
        assert np.allclose(d[k], DEPTH * p[k], rtol=1e-9, atol=1e-12 * np.max(np.abs(p[k]))), k
    assert np.all(d["energy.relative_residual"] <= 1e-9)
    assert deep.summary["plugins"]["geometry"]["name"] == "test-deep"
    assert deep.summary["case"]["geometry"] == {"length": planar.summary["case"]["geometry"]["length"],
                                                "radius": 0.5, "model": "test-deep", "depth": DEPTH}


def test_an_unknown_geometry_or_a_bad_depth_is_a_clear_error():
    with pytest.raises(CaseError, match=r"geometry.model = 'test-dep': no such geometry plugin; did you mean "
                                        r"'test-deep'"):
        load_case(CASES / "poiseuille-rigid.toml", ['geometry.model="test-dep"'], REGISTRY)
    with pytest.raises(CaseError, match=r"geometry.depth = -1.0: expected a number > 0.0"):
        load_case(CASES / "poiseuille-rigid.toml", ['geometry.model="test-deep"', "geometry.depth=-1.0"], REGISTRY)
    with pytest.raises(CaseError, match=r"geometry.depth = 2.0: unknown key"):
        load_case(CASES / "poiseuille-rigid.toml", ["geometry.depth=2.0"], REGISTRY)
