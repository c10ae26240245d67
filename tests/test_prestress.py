"""A prestressed start (``[initial] prestress``, multilayer/wall/prestress.py): the stress-free reference of the
finite-strain layers under which the wall imaged at P⁰ sits on the mesh.  Loaded from that reference to P⁰, the
wall comes back to the mesh to 1e-8 (an HGO two-layer tube of Holzapfel, Gasser & Ogden 2000, a thin HGO
membrane); the reference against the incompressible inflation of ``scripts/hgo_inflation.py`` and the membrane's
closed form; a fixed point that does not converge refused at ``initial.prestress``; a coupled run started there
does not move under P⁰, closes its ledger, and resumes bit-identically."""

import copy
import csv
import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from multilayer.case.casefile import validate_data
from multilayer.commands.main import main
from multilayer.plugin.problems import CaseError
from multilayer.plugin.registry import Registry
from multilayer.runner.loop import run_case
from multilayer.wall.equilibrium import static_deflection
from multilayer.wall.prestress import PrestressError, imbalance, prestress
from multilayer.wall.stack import LUMEN, Stack, WallSpace
from multilayer_plugins.axisymmetric import Axisymmetric
from multilayer_plugins.hyperelastic.band import hgo
from multilayer_plugins.hyperelastic.membrane import hgo_membrane, inflation_pressure

_spec = importlib.util.spec_from_file_location("hgo_inflation", Path(__file__).parents[1] / "scripts" / "hgo_inflation.py")
ref = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ref)

REGISTRY = Registry.load()
MMHG = 1333.22
P0 = 80.0 * MMHG
#: the static solves' tolerance (a band at κ = 3·10⁷ dyn/cm² has a round-off floor near 1e-11)
TOLERANCE = 1e-10


@pytest.mark.parametrize("lz", (1.0, 1.5))
def test_the_hgo_tube_loaded_from_its_reference_to_p0_sits_on_the_mesh(lz):
    """The rabbit carotid of HGO 2000 (media and adventitia, κ = 10³ c of the media, ends sliding) imaged at
    R_i = 0.71 mm under 80 mmHg: from its stress-free reference (d = D, the reference at the axial stretch
    λ_z) loaded to P⁰ in steps, the wall returns to the mesh within 1e-8 of |D|; the reference's inner radius
    inflates under P⁰ to the imaged one by the incompressible solution within 2 % (the bands' dilatation at
    κ = 10³ c moves it by 1.4 %, docs/theory-wall.md, "Inflation of a hyperelastic tube").

    Measured: |d|/|D| = 2.7e-10 (λ_z = 1), 2.9e-11 (1.5); r_i(P⁰) of the reference 0.07084 and 0.07005 cm.
    """
    layers = [hgo(1.1, layer.thickness, layer.c, 3.0e7, layer.k1, layer.k2, layer.beta, axial_stretch=lz,
                  ends="sliding") for layer in ref.CAROTID]
    space = WallSpace.build(layers, Axisymmetric(), 0.05, ref.INNER, 2, 2, [4, 2])
    found = prestress(Stack.assemble(space), P0, 0.0, tolerance=TOLERANCE)
    D = found.reference
    assert imbalance(found.stack, P0, 0.0) <= 1e-6
    d = static_deflection(found.stack, P0, 0.0, start=D, tolerance=TOLERANCE, steps_from=D)
    print(f"λ_z = {lz}: {found.iterations} iterations, |D| = {np.abs(D).max():.4g} cm, "
          f"|d|/|D| = {np.abs(d).max() / np.abs(D).max():.2e}")
    assert np.abs(d).max() <= 1e-8 * np.abs(D).max()
    unloaded = ref.INNER + float(np.mean(space.restrictions[LUMEN] @ D))
    assert ref.inner_radius(P0, lz, R_inner=unloaded) == pytest.approx(ref.INNER, rel=2e-2)


@pytest.mark.parametrize("lz", (1.0, 1.2))
def test_the_hgo_membrane_loaded_from_its_reference_to_p0_sits_on_the_mesh(lz):
    """An hgo-membrane tube (R = 0.3 cm imaged, ends pinned) at 80 mmHg: loaded from its reference (the ends'
    cells excepted: a pinned end is not at rest) to P⁰, it returns to the mesh within 1e-8 of |D|; mid-way, the
    reference radius R₀ holds R under P⁰ by the closed form p λθ = hΨ_θ/(λz0 R₀) to 1e-10.

    Measured: |d|/|D| = 4.9e-12 (λz0 = 1), 8.4e-12 (1.2)."""
    layer = hgo_membrane(1.06, 0.03, 3.0e5, 2.4e5, 0.8, 40.0, axial_stretch=lz)
    space = WallSpace.build([layer], Axisymmetric(), 2.0, 0.3, 40, 2)
    found = prestress(Stack.assemble(space), P0, 0.0, tolerance=1e-11)
    D = found.reference
    z = space.lines[LUMEN].z
    start = np.clip(np.minimum(z, 2.0 - z) / 0.2, 0.0, 1.0) * D
    d = static_deflection(found.stack, P0, 0.0, start=start, steps_from=start, tolerance=1e-11)
    assert np.abs(d).max() <= 1e-8 * np.abs(D).max()
    R0 = 0.3 + D[np.argmin(np.abs(z - 1.0))]
    assert inflation_pressure(layer, R0, 0.3 / R0) == pytest.approx(P0, rel=1e-10)


def test_a_fixed_point_that_does_not_converge_is_refused():
    """Two iterations are not enough for the HGO membrane of 80 mmHg (it takes 17): refused, with where the
    iteration stopped, its corrections and the out-of-balance force of the imaged wall."""
    layer = hgo_membrane(1.06, 0.03, 3.0e5, 2.4e5, 0.8, 40.0)
    space = WallSpace.build([layer], Axisymmetric(), 2.0, 0.3, 40, 2)
    with pytest.raises(PrestressError) as caught:
        prestress(Stack.assemble(space), P0, 0.0, max_iterations=2)
    message = str(caught.value)
    assert "did not converge in 2 iterations" in message and "last corrections" in message
    assert "relative out-of-balance force of the imaged wall" in message and "of initial.pressure" in message
    assert caught.value.residual > 1e-6


#: a 2 cm tube of the two HGO 2000 bands (R = 0.3 cm as imaged at 80 mmHg, ends sliding), monolithic BDF2
TUBE = {"geometry": {"model": "axisymmetric", "length": 2.0, "radius": 0.3},
        "mesh": {"nz": 4, "nr": 2, "order": 2}, "time": {"end": 5e-3, "dt": 1e-3},
        "fluid": {"model": "navier-stokes", "density": 1.06, "viscosity": 0.035},
        "coupler": {"model": "monolithic", "scheme": "bdf2"},
        "layers": [{"model": "hgo", "density": 1.1, "thickness": 0.072, "shear_modulus": 3.0e4,
                    "bulk_modulus": 3.0e7, "fibre_modulus": 2.3632e4, "fibre_exponent": 0.8393, "fibre_angle": 29.0,
                    "ends": "sliding", "cells": 2},
                   {"model": "hgo", "density": 1.1, "thickness": 0.042, "shear_modulus": 3.0e3,
                    "bulk_modulus": 3.0e7, "fibre_modulus": 5.62e3, "fibre_exponent": 0.7112, "fibre_angle": 62.0,
                    "ends": "sliding", "cells": 1}],
        "initial": {"pressure": P0, "prestress": True},
        "loads": {"inlet": P0, "outlet": P0},
        "output": {"probes": [{"name": "eta_mid", "quantity": "eta", "z": 1.0}]}}


def test_validation_refuses_a_prestress_it_cannot_give(tmp_path):
    data = copy.deepcopy(TUBE)
    del data["initial"]["pressure"]
    data["loads"] = {"inlet": 0.0, "outlet": 0.0}
    with pytest.raises(CaseError, match="initial.prestress = true: the geometry as imaged under initial.pressure"):
        validate_data(data, tmp_path, REGISTRY)
    data = copy.deepcopy(TUBE)
    data["layers"] = [{"model": "linear-elastic", "density": 1.1, "thickness": 0.1, "young": 4e6, "poisson": 0.45}]
    with pytest.raises(CaseError, match="initial.prestress.*no layer of the wall takes a stress-free reference"):
        validate_data(data, tmp_path, REGISTRY)


@pytest.mark.slow
def test_a_run_started_prestressed_does_not_move_under_p0_and_closes_its_ledger(tmp_path):
    """Five steps at constant P⁰ from the prestressed start: the wall stays on the mesh to round-off (|η| of
    1e-15 cm measured), the ledger closes; then a pressure pulse from it: the ledger still closes."""
    result = run_case(validate_data(copy.deepcopy(TUBE), tmp_path, REGISTRY), tmp_path / "rest", REGISTRY)
    assert result.status == "ok", result.reason
    with open(tmp_path / "rest" / "series.csv") as fh:
        eta = [abs(float(row["eta_mid"])) for row in csv.DictReader(fh)]
    assert max(eta) <= 1e-12
    summary = json.loads((tmp_path / "rest" / "summary.json").read_text())
    assert summary["energy"]["max_relative_residual"] <= 1e-9

    data = {**copy.deepcopy(TUBE), "time": {"end": 2e-3, "dt": 2.5e-4},
            "loads": {"inlet": f"{P0} + 2.0e4*sin(pi*t/2e-3)", "outlet": P0}}
    result = run_case(validate_data(data, tmp_path, REGISTRY), tmp_path / "pulse", REGISTRY)
    assert result.status == "ok", result.reason
    summary = json.loads((tmp_path / "pulse" / "summary.json").read_text())
    assert summary["energy"]["max_relative_residual"] <= 1e-9


def counting(monkeypatch) -> list[float]:
    """The pressures at which the stress-free reference is found from here on (validation's and the setup's
    calls of the fixed point)."""
    import multilayer.wall.prestress as module

    calls = []

    def counted(*args, **kwargs):
        calls.append(args[1])
        return module.prestress(*args, **kwargs)

    monkeypatch.setattr("multilayer.case.trial_walls.prestress", counted)
    monkeypatch.setattr("multilayer.scene.setup.prestress", counted)
    return calls


def test_the_reference_validation_found_is_the_one_the_run_sets_up_on(tmp_path, monkeypatch):
    """Validation finds the reference and the run's setup takes it (``Case.reference``): found once.  The setup
    on it is the one a setup finding the reference itself builds, bit for bit; the setup of a case changed since
    validation finds its own.  An hgo-membrane tube (the fixed point in a second)."""
    import attrs

    from multilayer.coupling.build import prepare

    calls = counting(monkeypatch)
    data = {**copy.deepcopy(TUBE), "mesh": {"nz": 8, "nr": 2, "order": 2},
            "layers": [{"model": "hgo-membrane", "density": 1.06, "thickness": 0.03, "c": 3.0e5, "k1": 2.4e5,
                        "k2": 0.8, "angle": 40.0}]}
    case = validate_data(data, tmp_path, REGISTRY)
    assert calls == [P0] and case.reference is not None
    setup = prepare(case, REGISTRY)[0]
    assert calls == [P0]
    assert setup.solvers["static"] == case.reference.stats and setup.solvers["static"] is not case.reference.stats
    own = prepare(attrs.evolve(case, reference=None), REGISTRY)[0]  # found by the setup
    assert calls == [P0, P0]
    zero = np.zeros(setup.stack.space.ndofs)
    assert np.array_equal(own.stack.force(zero), setup.stack.force(zero))
    assert (own.stack.tangent(zero) != setup.stack.tangent(zero)).nnz == 0
    assert own.solvers["static"].factorizations == setup.solvers["static"].factorizations > 0
    changed = attrs.evolve(case, initial=attrs.evolve(case.initial, pressure=0.9 * P0))
    prepare(changed, REGISTRY)
    assert calls == [P0, P0, 0.9 * P0]
    layers = attrs.evolve(case, layers=(attrs.evolve(case.layers[0], params={**case.layers[0].params, "c": 4e5}),))
    assert not case.reference.serves(layers) and case.reference.serves(attrs.evolve(case, title="another"))


@pytest.mark.slow
def test_a_prestressed_run_resumed_from_its_checkpoint_is_bit_identical(tmp_path, monkeypatch):
    """The reference is found once by a run and once by its resume, deterministically: the resumed run writes
    the same bytes."""
    calls = counting(monkeypatch)
    case = tmp_path / "tube.toml"
    data = {**copy.deepcopy(TUBE), "loads": {"inlet": f"{P0} + 2.0e4*sin(pi*t/2e-3)", "outlet": P0},
            "time": {"end": 1e-3, "dt": 2.5e-4}}
    case.write_text(_toml(data))

    def argv(out, end):
        return ["run", str(case), "--out", str(out), "--quiet", "--no-plots", "--checkpoint-every", "2",
                "--set", f"time.end={end}"]

    assert main(argv(tmp_path / "full", 1e-3)) == 0
    assert main(argv(tmp_path / "half", 5e-4)) == 0
    assert len(calls) == 2
    assert main(["resume", str(tmp_path / "half"), "--until", "1e-3", "--quiet", "--no-plots"]) == 0
    assert len(calls) == 3
    assert (tmp_path / "full" / "series.csv").read_bytes() == (tmp_path / "half" / "series.csv").read_bytes()


def _toml(data: dict) -> str:
    """The case ``data`` as a TOML file (tables of scalars, arrays of tables)."""
    def value(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + " }"
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)

    lines = []
    for key, table in data.items():
        if key == "layers":
            for layer in table:
                lines += ["[[layers]]", *(f"{k} = {value(v)}" for k, v in layer.items())]
        elif isinstance(table, dict):
            lines += [f"[{key}]", *(f"{k} = {value(v)}" for k, v in table.items())]
        else:
            lines.append(f"{key} = {value(table)}")
    return "\n".join(lines) + "\n"
