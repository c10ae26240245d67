"""Time schemes as plugins: every registered scheme against its energy identity, and a scheme from outside the package.

The θ-method of ``tests/theta_scheme.py`` is registered by hand, with no edit in ``multilayer/``:
``--plugin`` on the command line, ``Registry.load(extra=...)`` in the library.  Under every coupler
its ledger closes; its order is 1 for θ ≠ ½ (a wall mode against its exact solution, and a coupled
pulse against itself at halved steps); at θ = ½ and θ = 1 its weights are Crank–Nicolson's and
backward Euler's, and where its choices (its geometry at the θ-point) coincide with theirs it
computes the same bytes.  A multi-stage scheme (TR-BDF2) is refused by the couplers whose steps do not go
through the clock, for its stages, and BDF2's three levels by the paper's splitting alone.
"""

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
import theta_scheme
from runs import CASES, run_case_file, run_cli

from multilayer.case.casefile import load_case
from multilayer.commands.main import main
from multilayer.numerics.timescheme import named, schemes
from multilayer.plugin.problems import CaseError
from multilayer.plugin.registry import Registry

REGISTRY = Registry.load(extra=[theta_scheme])
THETA = str(Path(theta_scheme.__file__))
#: the ratios (ω, ω₋) a step is checked at: constant, growing, shrinking after a growth, growing after a shrink
RATIOS = [(1.0, 1.0), (1.7, 1.0), (0.4, 2.0), (2.0, 0.5)]
TINY = ("geometry.length=2.0", "mesh.nz=8", "mesh.nr=2", "time.end=0.002",
        'output.probes=[{ name = "eta_z1", quantity = "eta", z = 1.0 }]')


def theta(value: float) -> str:
    return f'{{model="theta",theta={value}}}'


def single_stage(registry: Registry) -> list[str]:
    return sorted(name for name, s in schemes(registry).items() if len(s.stages) == 1)


@pytest.mark.parametrize("name", single_stage(REGISTRY))
def test_every_registered_scheme_closes_its_energy_identity_at_any_step_ratio(name):
    """(Σα_k x^{n+1−k})ᵀ M x̄ = stored − before + numerical on random vectors, to round-off, at every step ratio
    the scheme takes; Σα = 0, Σβ = 1 and the difference quotient exact on a line through uneven steps."""
    base = named(name, REGISTRY)
    M = np.diag([2.0, 3.0, 0.5])
    q = lambda x: 0.5 * x @ M @ x  # noqa: E731
    rng = np.random.default_rng(1)
    for ratio, previous in RATIOS:
        if ratio >= base.max_ratio:
            continue
        S = base.with_ratio(ratio, previous)
        assert math.isclose(sum(S.alpha), 0.0, abs_tol=1e-14) and math.isclose(sum(S.beta), 1.0, rel_tol=1e-14)
        times = [1.0, 0.0, -1.0 / ratio, -1.0 / ratio - 1.0 / (ratio * previous)][:S.levels]
        assert math.isclose(float(S.difference([np.array(t) for t in times])), 1.0, rel_tol=1e-12)
        for _ in range(5):
            xs = [rng.normal(size=3) for _ in range(S.levels)]
            lhs = S.difference(xs) @ M @ S.average(xs)
            rhs = S.stored(q, xs) - S.before(q, xs) + S.numerical(q, xs)
            assert abs(lhs - rhs) <= 1e-12 * max(q(x) for x in xs), (name, ratio, previous)


@pytest.mark.parametrize("value", [0.5, 0.6, 0.75, 1.0])
def test_the_theta_method_closes_its_identity_and_takes_the_weights_of_its_ends(value):
    S = named("theta", REGISTRY, theta=value)
    M = np.diag([1.0, 4.0])
    q = lambda x: 0.5 * x @ M @ x  # noqa: E731
    xs = [np.array([1.0, -2.0]), np.array([0.3, 0.7])]
    assert abs(S.difference(xs) @ M @ S.average(xs) - (S.stored(q, xs) - S.before(q, xs) + S.numerical(q, xs))) < 1e-13
    assert S.numerical(q, xs) >= 0.0 and S.order == (2 if value == 0.5 else 1) and S.parameters == {"theta": value}
    assert S.geometry_position == value and S.stages[0].scheme.theta == value
    end = {0.5: named("crank-nicolson"), 1.0: named("backward-euler")}.get(value)
    if end is not None:
        assert (S.alpha, S.beta, S.old_levels, S.load_window(0.1, 0.3)) == (end.alpha, end.beta, end.old_levels,
                                                                            end.load_window(0.1, 0.3))


def problems(*sets: str, registry: Registry = REGISTRY, case: str = "pulse-koiter") -> list[str]:
    try:
        load_case(CASES / f"{case}.toml", sets, registry)
    except CaseError as exc:
        return [str(p) for p in exc.problems]
    return []


def test_a_scheme_is_validated_by_name_and_by_its_parameters():
    assert problems(f"coupler.scheme={theta(0.75)}") == []
    assert problems('coupler.scheme="theta"') == []  # its parameters' defaults
    found = problems(f"coupler.scheme={theta(0.3)}")
    assert found == ["coupler.scheme.theta = 0.3: expected a number >= 0.5 and <= 1.0 (from --set)"], found
    found = problems('coupler.scheme="crank-nicholson"')
    assert found == ["coupler.scheme = 'crank-nicholson': expected one of 'backward-euler', 'bdf2', 'crank-nicolson', "
                     "'theta', 'tr-bdf2'; did you mean 'crank-nicolson'? (from --set)"], found
    found = problems('coupler.scheme={model="thetta",theta=0.7}')
    assert len(found) == 1 and "did you mean 'theta'?" in found[0], found
    found = problems('coupler.scheme={theta=0.7}')
    assert len(found) == 1 and found[0].startswith("coupler.scheme = {'theta': 0.7}: expected the name of a scheme"), found
    # installed only: the test's scheme is unknown without its module
    assert problems(f"coupler.scheme={theta(0.75)}", registry=Registry.load()) == [
        "coupler.scheme = {'model': 'theta', 'theta': 0.75}: expected one of 'backward-euler', 'bdf2', "
        "'crank-nicolson', 'tr-bdf2' (from --set)"]


@pytest.mark.parametrize("coupler", ["kinematic-splitting", "kinematic-splitting-inertia", "monolithic",
                                     "dirichlet-neumann-implicit", "dirichlet-neumann-explicit", "fluid-only",
                                     "structure-only"])
def test_a_coupler_refuses_a_scheme_by_its_capabilities(coupler):
    """Two stages (TR-BDF2): taken by the couplers whose steps go through the clock, which steps the stages
    (``Coupler.multistage``), refused by Dirichlet–Neumann's, each naming the schemes it takes; a stage of three
    levels (BDF2's, TR-BDF2's second) by the paper's splitting alone (``robin = "inertia"``)."""
    case = {"fluid-only": "prescribed-wall", "structure-only": "membrane-mode"}.get(coupler, "pulse-koiter")
    model, *robin = coupler.split("-inertia")
    sets = (f"coupler.model={model}", *(['coupler.robin="inertia"'] if robin else []))
    found = problems(*sets, 'coupler.scheme="tr-bdf2"', case=case)
    bdf2 = problems(*sets, 'coupler.scheme="bdf2"', case=case)
    if coupler.startswith("dirichlet-neumann"):
        assert len(found) == 1 and found[0].startswith("coupler.scheme = 'tr-bdf2': tr-bdf2 has 2 stages a step"), found
        assert f"{model} takes 'backward-euler' or 'bdf2' or 'crank-nicolson' or 'theta'" in found[0], found
    elif robin:
        assert len(found) == 1 and found[0].startswith(
            "coupler.scheme = 'tr-bdf2': tr-bdf2 has a stage of 3 time levels"), found
        assert f"{model} takes 'backward-euler' or 'crank-nicolson' or 'theta'" in found[0], found
        assert len(bdf2) == 1 and "bdf2 has a stage of 3 time levels" in bdf2[0], bdf2
    else:
        assert found == [] and bdf2 == [], (found, bdf2)


def test_a_scheme_without_an_error_estimate_takes_no_adaptive_steps():
    found = problems(f"coupler={{model=\"monolithic\",scheme={theta(0.75)}}}", "time.tolerance=1e-3")
    assert found == ["coupler.model = 'monolithic': time.tolerance = 0.001 asks for adaptive steps, which monolithic "
                     "with scheme 'theta' does not take (no error estimate: theta is first order); it takes them with "
                     "scheme = 'bdf2' or 'crank-nicolson' or 'tr-bdf2', or remove time.tolerance (from --set)"], found


#: every coupler, on a case it runs, with what it needs
LEDGER = {
    "structure-only": ("membrane-mode", "time.end=0.004"),
    "fluid-only": ("prescribed-wall",),
    "kinematic-splitting": ("pulse-koiter", *TINY),
    "kinematic-splitting-inertia": ("pulse-koiter", *TINY, 'coupler.robin="inertia"', "coupler.beta=1",
                                    "solver.volume_margin=2"),
    "monolithic": ("pulse-koiter", *TINY),
    "monolithic-band": ("thick-wall", "mesh.nz=12", "mesh.nr=3", "time.end=0.002"),
    "dirichlet-neumann-implicit": ("pulse-koiter", *TINY, "coupler.tolerance=1e-11"),
    # explicit: stable for a heavy wall only (tests/test_partitioned.py); θ = 0.75 at ρ₁h/(ρ_f R) = 40 (at 10 its
    # energy outgrows the work in the first step, as Crank–Nicolson's does), its volume a step behind
    "dirichlet-neumann-explicit": ("pulse-koiter", *TINY, "layers[0].density=200", "solver.volume_margin=2"),
}


@pytest.mark.parametrize("coupler", LEDGER)
def test_the_theta_method_from_the_tests_folder_closes_the_ledger_under_every_coupler(coupler, tmp_path):
    """``--plugin tests/theta_scheme.py``: θ = 0.75 (first order, dissipative), ledger ≤ 1e-9 every step; the
    summary names the scheme and its parameter."""
    case, *sets = LEDGER[coupler]
    model = coupler.removesuffix("-inertia").removesuffix("-band")
    argv = ["run", str(CASES / f"{case}.toml"), "--out", str(tmp_path / "run"), "--quiet", "--no-plots",
            "--plugin", THETA, "--set", f"coupler.model={model}", "--set", f"coupler.scheme={theta(0.75)}"]
    for s in sets:
        argv += ["--set", s]
    assert main(argv) == 0
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    rows = list(csv.DictReader(open(tmp_path / "run" / "series.csv")))
    assert summary["status"] == "ok" and len(rows) == summary["steps"] > 0
    assert summary["scheme"] == {"name": "theta", "order": 1, "parameters": {"theta": 0.75}}
    assert summary["plugins"]["coupler.scheme"]["package"] == "theta_scheme"
    residuals = np.array([float(r["energy.relative_residual"]) for r in rows])
    assert np.all(residuals <= 1e-9), residuals.max()


def test_the_theta_method_is_first_order_on_a_wall_mode_and_second_at_one_half(tmp_path):
    """The membrane's mode 1 alone, η = 0.01 cos(ω₁t) at mid-length (ω₁ = (π/L)√(C1/ρh); the space error is
    ~1e-8): max error over 10 ms at Δt = 4e-5, 2e-5, 1e-5. Measured, relative to 0.01: θ = 0.75 3.08e-3, 1.53e-3,
    7.67e-4 (order 1.00); θ = 1 6.14e-3 → 1.53e-3 (1.00); θ = ½ 1.21e-5, 3.02e-6, 7.50e-7 (2.00)."""
    omega = math.pi / 6.0 * math.sqrt(2.0e4 / (1.1 * 0.1))
    for value, order in ((0.75, 1.0), (1.0, 1.0), (0.5, 2.0)):
        errors = []
        for dt in (4e-5, 2e-5, 1e-5):
            s = run_theta(tmp_path / f"{value}-{dt}", "membrane-mode", value, f"time.dt={dt}", "time.end=0.01")
            errors.append(np.max(np.abs(s["eta_mid"] - 0.01 * np.cos(omega * s["t"]))) / 0.01)
        orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
        assert np.all(np.abs(orders - order) < 0.02), (value, errors, orders)


@pytest.mark.parametrize("coupler", ["monolithic", "kinematic-splitting"])
def test_the_theta_method_is_first_order_under_a_coupler(coupler, tmp_path):
    """The pulse in the Koiter channel (20 × 4 cells, 4 ms), θ = 0.75, against itself at halved steps:
    Δt = 1e-4 … 1.25e-5. Measured differences of η(z = 1), both couplers: 3.6e-4, 2.0e-4, 1.06e-4, orders 0.84,
    0.92 (first order, approached from below as monolithic backward Euler's in tests/test_coupled.py)."""
    series = [run_theta(tmp_path / str(dt), "pulse-koiter", 0.75, "mesh.nz=20", "mesh.nr=4", "time.end=0.004", f"time.dt={dt}",
                        f"coupler.model={coupler}") for dt in (1e-4, 5e-5, 2.5e-5, 1.25e-5)]
    t = series[0]["t"]
    eta = [np.interp(t, s["t"], s["eta_z1"]) for s in series]
    differences = np.array([np.max(np.abs(a - b)) for a, b in zip(eta, eta[1:])])
    orders = np.log2(differences[:-1] / differences[1:])
    assert np.all(np.diff(orders) > 0) and 0.85 < orders[-1] < 1.15, (differences, orders)


def run_theta(out: Path, case: str, value: float, *sets: str) -> dict[str, np.ndarray]:
    """``case`` with the θ-method of this folder (``Registry.load(extra=...)``, the library's way): its series."""
    result, data = run_case_file(case, out, f"coupler.scheme={theta(value)}", *sets, registry=REGISTRY)
    assert result.status == "ok", result.reason
    return {k: np.asarray(v, dtype=float) for k, v in data.series.items()}


@pytest.mark.parametrize("value, scheme, coupler, case", [
    (0.5, "crank-nicolson", "monolithic", "pulse-koiter"),
    (0.5, "crank-nicolson", "kinematic-splitting", "pulse-koiter"),
    (0.5, "crank-nicolson", "dirichlet-neumann-implicit", "pulse-koiter"),
    (1.0, "backward-euler", "structure-only", "membrane-mode"),
])
def test_the_theta_method_computes_the_bytes_of_the_scheme_it_coincides_with(value, scheme, coupler, case, tmp_path):
    """θ = ½ is Crank–Nicolson in every choice (weights, midpoint geometry, order, load window), so its series.csv
    is Crank–Nicolson's byte for byte; θ = 1 is backward Euler's on a wall alone (its fluid would sit on the new
    domain, backward Euler's on the old)."""
    sets = (*TINY, f"coupler.model={coupler}") if case == "pulse-koiter" else ("time.end=0.004",)
    code, _, _ = run_cli(case, tmp_path / "ours", *sets, f'coupler.scheme="{scheme}"')
    assert code == 0
    argv = ["run", str(CASES / f"{case}.toml"), "--out", str(tmp_path / "theirs"), "--quiet", "--no-plots",
            "--plugin", THETA, *(a for s in (*sets, f"coupler.scheme={theta(value)}") for a in ("--set", s))]
    assert main(argv) == 0
    assert (tmp_path / "ours" / "series.csv").read_bytes() == (tmp_path / "theirs" / "series.csv").read_bytes()


def test_plugins_lists_the_schemes_and_a_scheme_s_parameters(capsys):
    assert main(["plugins"]) == 0
    rows = [line.split()[:3] for line in capsys.readouterr().out.splitlines()]
    assert {("scheme", n, "multilayer") for n in ("backward-euler", "bdf2", "crank-nicolson")} <= set(map(tuple, rows))
    assert main(["plugins", "theta", "--plugin", THETA]) == 0
    out = capsys.readouterr().out
    assert out.startswith("scheme theta (theta_scheme") and any(line.split()[:3] == ["theta", "1", "1.0"]
                                                                for line in out.splitlines())
    assert main(["plugins", "monolithic"]) == 0
    assert "the name of a scheme plugin, or a table {model = name, ...}" in capsys.readouterr().out
