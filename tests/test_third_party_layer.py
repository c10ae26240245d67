"""A layer model written outside the package is found and used: no core edit needed.

The Winkler foundation ρ η_tt + k η = f is registered from this test module
(not from ``multilayer_plugins/``); its run must ring at ω = √(k/ρ) for any mode.
"""

import csv
import sys

import numpy as np
import skfem

from multilayer.case.casefile import validate_data
from multilayer.numerics.signals import backward_euler_eigenvalue, prony_roots
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import LayerPlugin, Param
from multilayer.plugin.registry import Registry
from multilayer.runner.loop import run_case
from multilayer.testing import LayerConformance
from multilayer.wall.layer import LayerMatrices, ThinLayer


@skfem.BilinearForm
def mass(eta, psi, w):
    return eta * psi


class Winkler(ThinLayer):
    def __init__(self, density, foundation):
        self.density, self.foundation = density, foundation

    def forms(self, space):
        M = mass.assemble(space.basis).tocsr()
        return LayerMatrices(self.density * M, 0.0 * M, self.foundation * M)


@hookimpl
def multilayer_layers():
    return [LayerPlugin("winkler", Winkler, (Param("density", "ρ", "g/cm²", gt=0.0, doc="areal mass"),
                                            Param("foundation", "k", "dyn/cm³", gt=0.0, doc="spring stiffness")),
                        "A wall on a Winkler foundation.", thin=True)]


CASE = {
    "geometry": {"length": 6.0, "radius": 0.5},
    "mesh": {"nz": 20, "nr": 1, "order": 2},
    "time": {"end": 0.01, "dt": 1e-5},
    "fluid": "none",
    "layers": [{"model": "winkler", "density": 0.11, "foundation": 4.4e4}],
    "initial": {"displacement": {"r": "0.01*sin(3*pi*z/L)"}},
    "output": {"probes": [{"name": "eta", "quantity": "eta", "z": 1.0}]},
}


def test_third_party_layer_is_registered_and_rings_at_its_own_frequency(tmp_path):
    registry = Registry.load(extra=[sys.modules[__name__]])
    assert registry.get("layer", "winkler").package == __name__.split(".")[0]
    case = validate_data(CASE, tmp_path, registry)
    result = run_case(case, tmp_path / "out", registry)
    assert result.status == "ok" and result.max_relative_residual < 1e-10
    rows = list(csv.DictReader(open(tmp_path / "out" / "series.csv")))
    z = prony_roots(np.array([float(r["eta"]) for r in rows]), 2)
    lam = backward_euler_eigenvalue(z[np.argmax(np.angle(z))], 1e-5)
    assert abs(abs(lam.imag) - np.sqrt(4.4e4 / 0.11)) / np.sqrt(4.4e4 / 0.11) < 1e-9


class TestWinklerConforms(LayerConformance):
    """The conformance kit, run the way a third party runs it in its own tests."""

    layer = "winkler"
    plugins = (sys.modules[__name__],)
