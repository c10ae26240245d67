"""A nonlinear layer (``tests/nonlinear_layers.py``: a membrane on cubic springs) through the residual/tangent
contract and the one Newton loop: the conformance kit, every coupler that takes a thin layer with its energy
ledger closed every step, Newton's quadratic convergence, the discrete gradient of Crank–Nicolson, the static
start, and a linear wall's one correction."""

import copy
from pathlib import Path

import nonlinear_layers
import numpy as np
import pytest

from multilayer.case.casefile import validate_data
from multilayer.commands.main import main
from multilayer.coupling import structure
from multilayer.coupling.structure import StructureStep
from multilayer.numerics.linsolve import SolverStats
from multilayer.numerics.timescheme import named
from multilayer.plugin.problems import CaseError
from multilayer.plugin.registry import Registry
from multilayer.results.reading import read_run
from multilayer.runner.loop import run_case
from multilayer.scene.setup import Setup
from multilayer.testing import LayerConformance, check_layer
from multilayer.wall.equilibrium import static_deflection
from multilayer.wall.stack import LUMEN

REGISTRY = Registry.load(extra=[nonlinear_layers])
LAYER = {"model": "cubic-spring-membrane", **nonlinear_layers.EXAMPLE}
K, K3 = nonlinear_layers.EXAMPLE["spring"], nonlinear_layers.EXAMPLE["cubic"]
PROBES = [{"name": f"eta_z{k}", "quantity": "eta", "z": float(k)} for k in (1, 2, 3)]
#: a pressure pulse through a coarse channel; the springs stiffer than the example's so that the fluid's pulse
#: (which the fluid takes most of) still reaches k₃η² ~ k
FLUID = {"geometry": {"length": 6.0, "radius": 0.5}, "mesh": {"nz": 12, "nr": 3, "order": 2},
         "time": {"end": 3e-3, "dt": 1e-4}, "fluid": {"model": "navier-stokes", "density": 1.0, "viscosity": 0.035},
         "layers": [{**LAYER, "cubic": 2e9, "damping": 10.0, "cubic_damping": 1.0}],
         "loads": {"inlet": {"model": "cosine-pulse", "amplitude": 1.3e4, "duration": 3e-3}},
         "output": {"probes": PROBES}}
#: a band behind the membrane (theory §9's composite wall's)
BAND = {"model": "linear-elastic", "density": 1.1, "thickness": 0.1, "young": 7.5e5, "poisson": 0.45, "cells": 2}
#: the wall alone under the same pulse on its lumen
SOLID = {**FLUID, "fluid": "none", "layers": [{**LAYER, "damping": 10.0, "cubic_damping": 1.0}],
         "loads": {"interface": {"model": "cosine-pulse", "amplitude": 1.3e4, "duration": 3e-3}}}
#: the wall alone ringing from a large initial deflection (k₃η² = 4k at its crest), no damping, no load
RINGING = {**SOLID, "layers": [LAYER], "loads": {}, "time": {"end": 2e-3, "dt": 1e-4},
           "initial": {"displacement": {"r": "0.1*sin(pi*z/L)"}}}


class TestCubicSpringMembraneConforms(LayerConformance):
    """The kit, run as a third party runs it; its coupled run is monolithic (the layer is nonlinear)."""

    layer = "cubic-spring-membrane"
    plugins = (nonlinear_layers,)


@pytest.mark.parametrize("name, words", [
    ("broken-cubic-tangent", "the tangent is not the derivative of the force"),
    ("broken-cubic-energy", "the force is not the gradient of the energy"),
    ("broken-cubic-declared-linear", "but the layer declares linear = True"),
])
def test_the_kit_finds_a_wrong_tangent_energy_or_declaration(tmp_path, name, words):
    (result,) = check_layer(name, plugins=[nonlinear_layers], checks=("forces",), workdir=tmp_path)
    assert not result.ok and words in "; ".join(result.problems), str(result)


def test_validation_refuses_nonlinear_forms_declared_linear(tmp_path):
    data = {**RINGING, "layers": [{**LAYER, "model": "broken-cubic-declared-linear"}]}
    with pytest.raises(CaseError, match="layers\\[0\\]: broken-cubic-declared-linear: forms returned nonlinear forms "
                                        "\\(CubicSpringForms\\), but the layer declares linear = True"):
        validate_data(data, tmp_path, REGISTRY)


def run(tmp_path: Path, base: dict, coupler: dict, name: str = "run", **changes):
    """Run ``base`` under ``coupler`` (with ``changes`` to its top-level tables): (RunResult, RunData)."""
    data = copy.deepcopy(base)
    data["coupler"] = coupler
    data.update(changes)
    case = validate_data(data, tmp_path, REGISTRY)
    result = run_case(case, tmp_path / name, REGISTRY)
    return result, read_run(name, tmp_path / name)


def _name(coupler: dict, changes: dict) -> str:
    layers = "-on-a-band" if len(changes.get("layers", ())) > 1 else ""
    return f"{coupler['model']}-{coupler.get('scheme', 'backward-euler')}{layers}"


COUPLERS = [
    (SOLID, {"model": "structure-only", "scheme": "backward-euler"}, {}),
    (SOLID, {"model": "structure-only", "scheme": "crank-nicolson"}, {}),
    (SOLID, {"model": "structure-only", "scheme": "bdf2"}, {}),
    (SOLID, {"model": "structure-only", "scheme": "tr-bdf2"}, {}),
    (FLUID, {"model": "monolithic", "scheme": "backward-euler"}, {}),
    (FLUID, {"model": "monolithic", "scheme": "crank-nicolson"}, {}),
    (FLUID, {"model": "monolithic", "scheme": "bdf2"}, {}),
    (FLUID, {"model": "monolithic", "scheme": "tr-bdf2"}, {}),
    # the paper's Robin term loses volume through the wall at this Δt (docs/theory.md, "Volume"): not the point here
    (FLUID, {"model": "kinematic-splitting", "robin": "inertia"}, {"solver": {"volume_margin": 1e9}}),
    (FLUID, {"model": "kinematic-splitting", "robin": "inertia", "scheme": "crank-nicolson", "beta": 1.0},
     {"solver": {"volume_margin": 1e9}}),
    (FLUID, {"model": "dirichlet-neumann-implicit", "scheme": "backward-euler"}, {}),
    (FLUID, {"model": "dirichlet-neumann-implicit", "scheme": "crank-nicolson"}, {}),
    # the nonlinear membrane on a band: its forces moved into the wall's numbering, Crank–Nicolson's correction on
    # the membrane's DOFs
    (FLUID, {"model": "monolithic", "scheme": "crank-nicolson"}, {"layers": [FLUID["layers"][0], BAND]}),
    # explicit Dirichlet–Neumann: a heavier wall, and its interface's energy and volume errors let through
    (FLUID, {"model": "dirichlet-neumann-explicit"},
     {"layers": [{**FLUID["layers"][0], "density": 20.0}], "solver": {"energy_margin": 1e9, "volume_margin": 1e9}}),
]


@pytest.mark.parametrize("base, coupler, changes", COUPLERS,
                         ids=[_name(c, changes) for _, c, changes in COUPLERS])
def test_every_coupler_closes_the_ledger_every_step_with_a_nonlinear_layer(tmp_path, base, coupler, changes):
    result, data = run(tmp_path, base, coupler, **changes)
    assert result.status == "ok", result.reason
    assert np.max(data.series["energy.relative_residual"]) <= 1e-9
    # the springs were well into their nonlinear range: k₃η² ≥ k/3 at the peak
    k3 = (changes.get("layers") or base["layers"])[0]["cubic"]
    eta = max(np.max(np.abs(data.series[p["name"]])) for p in PROBES)
    assert k3 * eta**2 >= K / 3.0, eta
    # and every solve iterated to the loop's tolerance
    (newton,) = data.summary["newton"].values()
    assert newton["solves"] >= 30 and newton["max_iterations"] >= 3 and newton["max_residual"] <= 1e-11


def test_crank_nicolsons_correction_stays_on_the_layer():
    """The discrete gradient of the membrane on a band corrects only the membrane's DOFs (the lumen line's)."""
    data = {**FLUID, "layers": [FLUID["layers"][0], BAND], "coupler": {"model": "monolithic"}}
    setup = Setup.build(validate_data(data, "/tmp", REGISTRY), REGISTRY)
    forms, space = setup.stack.matrices[0], setup.wall
    rng = np.random.default_rng(1)
    d0, d1 = (setup.stack.zero_fixed(0.05 * rng.standard_normal(space.ndofs)) for _ in range(2))
    f = structure.step_force(named("crank-nicolson"), forms, [d1, d0])
    assert abs(float(f @ (d1 - d0)) - (forms.elastic(d1) - forms.elastic(d0))) <= 1e-12 * forms.elastic(d1)
    off = np.setdiff1d(np.arange(space.ndofs), space.line_dofs(LUMEN))
    assert not np.any(f[off]) and np.any(f - forms.force(0.5 * (d0 + d1)))


def test_the_splitting_refuses_a_nonlinear_wall_under_its_impedance(tmp_path):
    """Its A3 completes the wall's step by the wall's linear response; the paper's Robin term is accepted."""
    data = {**FLUID, "coupler": {"model": "kinematic-splitting"}}
    with pytest.raises(CaseError, match="layers\\[0\\] \\('cubic-spring-membrane'\\) is nonlinear, which "
                                        "kinematic-splitting with robin = 'impedance' cannot take: .*response depends "
                                        "on the load.*set coupler.robin = 'inertia'"):
        validate_data(data, tmp_path, REGISTRY)
    validate_data({**data, "coupler": {"model": "kinematic-splitting", "robin": "inertia"}}, tmp_path, REGISTRY)


def one_step(layer: dict, scheme: str, dt: float, stats: SolverStats | None = None):
    """One wall step of RINGING's wall (with ``layer``) from its initial deflection: the WallStep."""
    data = {**RINGING, "layers": [layer], "time": {"end": dt, "dt": dt}}
    setup = Setup.build(validate_data(data, "/tmp", REGISTRY), REGISTRY)
    step = StructureStep(setup.stack, named(scheme), dt, stats or SolverStats())
    return step.step(setup.initial_state(), {})


def test_newton_converges_quadratically():
    """Backward Euler's tangent is the exact derivative of its residual: once near, each relative residual is
    at most the square of the one before.  With the tangent's cubic term off by 3 (the broken layer) the same
    step converges only linearly: the assertion tells the two apart."""
    residuals = one_step(LAYER, "backward-euler", 1e-3).newton.residuals
    # measured: 1.0, 7.4e-01, 2.9e-01, 3.7e-02, 6.5e-04, 2.2e-07, 2.5e-14
    assert len(residuals) >= 6 and residuals[-1] <= 1e-13
    tail = residuals[-4:]
    assert all(b <= a * a for a, b in zip(tail, tail[1:])), residuals
    wrong = one_step({**LAYER, "model": "broken-cubic-tangent"}, "backward-euler", 1e-3).newton.residuals
    assert len(wrong) > len(residuals) and not all(b <= a * a for a, b in zip(wrong[-4:], wrong[-3:])), wrong


def test_a_linear_wall_takes_one_correction_and_evaluates_no_residual():
    stats = SolverStats()
    result = one_step({**LAYER, "model": "cubic-spring-twin"}, "crank-nicolson", 1e-4, stats).newton
    assert (result.iterations, result.residuals) == (1, ())
    assert stats.newton_solves == 0 and stats.factorizations == 1


@pytest.mark.parametrize("scheme", ["backward-euler", "crank-nicolson", "bdf2"])
def test_without_its_cubic_terms_the_newton_loop_is_the_linear_step(tmp_path, scheme):
    """k₃ = D3 = 0 as nonlinear forms (Newton, GMRES on held factors) and as linear ones (one back-substitution):
    the same wall to the loop's tolerance."""
    ringing = {**RINGING, "layers": [{**LAYER, "cubic": 0.0, "damping": 30.0}]}
    _, nonlinear = run(tmp_path, ringing, {"model": "structure-only", "scheme": scheme}, "nonlinear")
    twin = {**ringing, "layers": [{**ringing["layers"][0], "model": "cubic-spring-twin"}]}
    _, linear = run(tmp_path, twin, {"model": "structure-only", "scheme": scheme}, "linear")
    assert "newton" in nonlinear.summary and "newton" not in linear.summary
    for p in PROBES:
        a, b = nonlinear.series[p["name"]], linear.series[p["name"]]
        assert np.max(np.abs(a - b)) <= 1e-10 * np.max(np.abs(b)), p["name"]


def test_crank_nicolson_conserves_the_nonlinear_energy(tmp_path, monkeypatch):
    """The discrete gradient makes f̄·Δd = W(d¹) − W(d⁰): the undamped ringing keeps its energy to round-off.
    The midpoint force alone (its correction left out) does not."""
    coupler = {"model": "structure-only", "scheme": "crank-nicolson"}
    _, data = run(tmp_path, RINGING, coupler, "gradient")
    energy = data.series["energy.total"]
    assert np.max(np.abs(data.series["dissipation.numerical.wall"])) <= 1e-12 * energy[0]
    assert np.max(np.abs(energy - energy[0])) <= 5e-11 * energy[0]  # measured 4.5e-12: the Newton tolerance's
    monkeypatch.setattr(structure, "GRADIENT_ROUND_OFF", np.inf)
    _, midpoint = run(tmp_path, RINGING, coupler, "midpoint")
    drift = midpoint.series["energy.total"] - midpoint.series["energy.total"][0]
    assert np.max(np.abs(drift)) >= 1e-3 * energy[0]  # measured 0.8 %
    assert np.max(midpoint.series["energy.relative_residual"]) <= 1e-9  # closed by the remainder, not conserved


def test_backward_euler_dissipates_the_nonlinear_energy(tmp_path):
    """W(dⁿ) − W(dⁿ⁺¹) + f(dⁿ⁺¹)·Δd ≥ 0 for a convex W: the numerical dissipation is never negative."""
    _, data = run(tmp_path, RINGING, {"model": "structure-only", "scheme": "backward-euler"})
    numerical = data.series["dissipation.numerical.wall"]
    assert np.min(numerical) > 0.0 and np.max(data.series["energy.relative_residual"]) <= 1e-9


def test_the_static_start_solves_the_nonlinear_equilibrium():
    """A uniform pressure P on a long planar membrane: away from the pinned ends k η + k₃η³ = P (the tension's
    boundary layer, √(C1/k_T) = 0.19 cm with the tangent k_T = k + 3k₃η², has decayed by e⁻¹⁶ at the middle);
    the out-of-balance force is at the Newton loop's tolerance."""
    P = 1.3e4
    data = {**FLUID, "layers": [LAYER], "coupler": {"model": "monolithic"}, "initial": {"pressure": P}}
    setup = Setup.build(validate_data(data, "/tmp", REGISTRY), REGISTRY)
    stats = SolverStats()
    d = static_deflection(setup.stack, P, 0.0, stats)
    eta = setup.wall.restrictions[LUMEN] @ d
    middle = eta[np.argmin(np.abs(setup.wall.lines[LUMEN].z - 3.0))]
    root = np.roots([K3, 0.0, K, -P])
    exact = float(root[np.argmin(np.abs(root.imag))].real)
    assert abs(middle - exact) <= 1e-5 * exact and K3 * exact**2 >= K / 2  # measured 5e-7; in the cubic range
    f = P * setup.wall.line_load(LUMEN)
    r = (f - setup.stack.force(d))[setup.stack.free]
    assert np.linalg.norm(r) <= 1e-11 * np.linalg.norm(f[setup.stack.free])
    assert stats.newton_solves == 1 and stats.newton_max_iterations >= 4


@pytest.mark.parametrize("scheme", ["backward-euler", "crank-nicolson"])
def test_a_run_started_at_the_nonlinear_equilibrium_stays_at_rest(tmp_path, scheme):
    """In a tube (the pressure on the moved lumen: the static start iterates), the fluid at rest at P⁰ = the
    ends' pressure: η and Q do not move."""
    P = 5.0e3
    _, data = run(tmp_path, FLUID, {"model": "monolithic", "scheme": scheme},
                  geometry={"model": "axisymmetric", "length": 6.0, "radius": 0.5}, initial={"pressure": P},
                  loads={"inlet": P, "outlet": P}, time={"end": 1e-3, "dt": 2e-4},
                  output={"probes": PROBES + [{"name": "q_in", "quantity": "flow_rate", "z": 0.0}]})
    eta = np.array([data.series[p["name"]] for p in PROBES])
    k3 = FLUID["layers"][0]["cubic"]
    assert k3 * np.min(eta) ** 2 >= K / 3.0  # deflected into the cubic range
    assert np.max(np.abs(eta - eta[:, :1])) <= 1e-9 * np.max(eta)
    assert np.max(np.abs(data.series["q_in"])) <= 1e-7


CASE_FILE = """
title = "a membrane on cubic springs, monolithic Crank-Nicolson"
[geometry]
length = 6.0
radius = 0.5
[mesh]
nz = 12
nr = 3
order = 2
[time]
end = {end}
dt = 1e-4
[fluid]
model = "navier-stokes"
density = 1.0
viscosity = 0.035
[[layers]]
model = "cubic-spring-membrane"
density = 1.1
thickness = 0.1
tension = 2.0e4
spring = 2.0e5
cubic = 2.0e9
[coupler]
model = "monolithic"
scheme = "crank-nicolson"
[loads]
inlet = {{ model = "cosine-pulse", amplitude = 1.3e4, duration = 3e-3 }}
"""


def test_a_resumed_nonlinear_run_is_bit_identical(tmp_path):
    """The wall's Newton loop holds a factorization between steps (its ReusingSolver): a checkpoint keeps it."""
    plugin = str(Path(nonlinear_layers.__file__))
    paths = {}
    for name, end in (("full", 0.002), ("half", 0.001)):
        paths[name] = tmp_path / f"{name}.toml"
        paths[name].write_text(CASE_FILE.format(end=end))
        assert main(["run", str(paths[name]), "--out", str(tmp_path / name), "--quiet", "--no-plots",
                     "--checkpoint-every", "5", "--plugin", plugin]) == 0
    assert main(["resume", str(tmp_path / "half"), "--until", "0.002", "--quiet", "--no-plots",
                 "--plugin", plugin]) == 0
    for table in ("series.csv", "eta_lumen.csv"):
        assert (tmp_path / "full" / table).read_bytes() == (tmp_path / "half" / table).read_bytes(), table


DOCS = Path(__file__).parents[1] / "docs" / "plugins.md"
NONLINEAR_EXAMPLE = next(block.split("```", 1)[0] for block in DOCS.read_text().split("```python\n")[1:]
                         if "class StiffeningSpring" in block)


def test_the_nonlinear_layer_of_the_docs_passes_check_plugin(tmp_path, capsys):
    path = tmp_path / "stiffening_spring.py"
    path.write_text(NONLINEAR_EXAMPLE)
    assert main(["check-plugin", "stiffening-spring", "--plugin", str(path)]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == "all 6 checks passed"
