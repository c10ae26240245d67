"""Case files: the format, defaults, overrides, and every mistake told in the user's words."""

import hashlib
import json
import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import fake_plugins
import numpy as np
import pytest

from multilayer.case.casefile import (
    CaseError,
    coupler_problems,
    load_case,
    validate_data,
)
from multilayer.case.keys import apply_overrides, parse_value
from multilayer.commands.main import main
from multilayer.plugin.registry import Registry

# -- validation against stand-in plugins (independent of the real models) -------

FAKES = Registry.load(extra=[fake_plugins], entry_points=False)

CASE = textwrap.dedent(
    """\
    title = "pulse"

    [geometry]
    length = 6.0
    radius = 0.5

    [mesh]
    nz = 12
    nr = 4
    order = 2

    [time]
    end = 0.012
    dt = 1e-4

    [fluid]
    model = "navier-stokes"
    density = 1.0
    viscosity = 0.035

    [[layers]]
    model = "koiter-shell"
    density = 1.1
    thickness = 0.02
    young = 7.5e5
    poisson = 0.45

    [[layers]]
    model = "linear-elastic"
    density = 1
    thickness = 0.1
    young = 9e5
    poisson = 0.4

    [loads]
    inlet = { model = "cosine-pulse", amplitude = 1.3333e4, duration = 0.003 }
    outlet = "0"
    external = { model = "table", file = "pe.csv", period = 0.01 }

    [initial]
    displacement = { r = "0.01*sin(pi*z/L)*H/R" }

    [output]
    every = 10
    probes = [
        { name = "eta_mid", quantity = "eta", z = 3.0 },
        { quantity = "d_r", z = 3.0, r = 0.55 },
        { quantity = "flow_rate", z = 6.0 },
    ]
    """
)


@pytest.fixture
def case_file(tmp_path):
    (tmp_path / "pe.csv").write_text("t,p\n0,0\n0.005,10\n")
    path = tmp_path / "case.toml"
    path.write_text(CASE)
    return path


def test_a_valid_case_with_its_defaults(case_file):
    case = load_case(case_file, registry=FAKES)
    assert case.title == "pulse"
    assert (case.geometry.length, case.geometry.radius) == (6.0, 0.5)
    assert (case.mesh.nz, case.mesh.nr, case.mesh.order, case.mesh.grading) == (12, 4, 2, 1.0)
    assert case.time.steps == 120
    assert case.fluid.model == "navier-stokes" and case.fluid.params == {"density": 1.0, "viscosity": 0.035}
    shell, band = case.layers
    assert (shell.path, shell.thin, shell.cells) == ("layers[0]", True, None)
    assert shell.params["viscosity"] == 0.0  # a plugin default, filled in
    assert (band.thin, band.cells) == (False, 4)
    assert type(band.params["density"]) is float  # an int is accepted for a float
    assert case.coupler.model == "kinematic-splitting"  # the default with a fluid
    assert case.loads.inlet.model == "cosine-pulse" and case.loads.interface.average(0, 1) == 0.0
    assert case.loads.external.average(0.0, 0.01) == pytest.approx(5.0)
    # H is the total thickness of the thick bands
    assert float(case.initial.displacement_r(z=3.0)) == pytest.approx(0.01 * 0.1 / 0.5)
    assert float(case.initial.velocity_z(z=1.0)) == 0.0
    names = [p.name for p in case.output.probes]
    assert names == ["eta_mid", "d_r_z3_r0.55", "flow_rate_z6"]
    assert case.solver == "superlu"


def test_resolved_case_and_its_digest(case_file):
    case = load_case(case_file, registry=FAKES)
    text = json.dumps(case.resolved, sort_keys=True, separators=(",", ":"))
    assert case.digest == hashlib.sha256(text.encode()).hexdigest()
    assert case.resolved["coupler"] == {"model": "kinematic-splitting"}
    assert case.resolved["layers"][1]["cells"] == 4 and "cells" not in case.resolved["layers"][0]
    assert case.resolved["loads"]["outlet"] == {"model": "formula", "expr": "0"}
    assert case.resolved["loads"]["external"]["sha256"] == hashlib.sha256(b"t,p\n0,0\n0.005,10\n").hexdigest()
    # the resolved data is itself a valid case, and the same case
    again = validate_data(json.loads(json.dumps(case.resolved)), case_file.parent, FAKES)
    assert again.digest == case.digest
    # any change of a value changes the digest; so does a change of a table file
    assert load_case(case_file, ["layers[0].young=7.6e5"], FAKES).digest != case.digest
    (case_file.parent / "pe.csv").write_text("t,p\n0,0\n0.005,11\n")
    assert load_case(case_file, registry=FAKES).digest != case.digest


def test_fluid_none_changes_the_default_coupler(case_file):
    case = load_case(case_file, ["fluid=none", "output.probes[2].quantity=eta"], FAKES)
    assert case.fluid is None and case.coupler.model == "structure-only"


@pytest.mark.parametrize(
    "text, value",
    [("5e-5", 5e-5), ("12", 12), ("true", True), ('"a b"', "a b"), ("koiter-shell", "koiter-shell"),
     (".5", 0.5), ("[1, 2]", [1, 2]), ("{ r = '0' }", {"r": "0"}), ("none", "none")],
)
def test_override_values(text, value):
    assert parse_value(text) == value


def test_overrides_numbers_strings_and_list_entries(case_file):
    case = load_case(
        case_file,
        ["time.dt=5e-5", "layers[1].young=1e6", 'title="renamed"', "mesh.grading=2",
         "output.probes[0].z=1.5", "solver.linear=superlu",
         'layers[0]={ model = "wave-membrane", density = 1.1, thickness = 0.1, tension = 2e4 }'],
        FAKES,
    )
    assert case.time.dt == 5e-5 and case.time.steps == 240
    assert case.title == "renamed" and case.mesh.grading == 2.0
    assert case.output.probes[0].z == 1.5
    assert case.layers[1].params["young"] == 1e6
    assert case.layers[0].model == "wave-membrane" and case.layers[0].params["tension"] == 2e4


def test_override_to_another_model_is_checked_against_its_schema(case_file):
    with pytest.raises(CaseError) as info:
        load_case(case_file, ["layers[0].model=wave-membrane"], FAKES)
    text = str(info.value)
    assert "layers[0].young = 750000.0: unknown key" in text and "(from --set)" not in text.split("young")[0]
    assert "layers[0].tension: missing" in text


def test_override_problems():
    data = {"time": {"dt": 1.0}, "layers": [{"model": "x"}]}
    problems = apply_overrides(data, ["time", "layers[1].young=1", "time.dt.x=1", "layers.x=1", "a b=1"])
    assert [p.path for p in problems] == ["--set", "layers[1]", "time.dt", "layers", "--set"]
    assert apply_overrides(data, ["solver.linear=superlu"]) == [] and data["solver"] == {"linear": "superlu"}


def test_all_problems_in_one_pass(case_file):
    with pytest.raises(CaseError) as info:
        load_case(case_file, ["mesh.nz=0", "layers[0].poisson=0.5", "layers[1].density=-1", "time.dt=0"], FAKES)
    paths = [p.path for p in info.value.problems]
    assert paths == ["mesh.nz", "time.dt", "layers[0].poisson", "layers[1].density"]
    assert len(str(info.value).splitlines()) == 4


def test_cross_field_constraint_from_the_factory(case_file):
    with pytest.raises(CaseError, match=r"^layers\[1\]: linear-elastic: young and poisson give no positive"):
        load_case(case_file, ["layers[1].young=1e13"], FAKES)


def test_coupler_check_case(case_file):
    with pytest.raises(CaseError, match=r"coupler.model = 'kinematic-splitting': kinematic-splitting needs a fluid"):
        load_case(case_file, ["fluid=none", "coupler=kinematic-splitting", "output.probes[2].quantity=eta"], FAKES)
    case = load_case(case_file, registry=FAKES)
    assert coupler_problems(case, FAKES) == []


def test_a_coupler_known_by_energy_and_evolve_alone_leaves_the_static_start_to_the_run(case_file):
    """The fake coupler has no radial_lines or fluid_wall (the Coupler base class's): validation does not ask."""
    assert load_case(case_file, ["initial={pressure=1e9}"], FAKES).initial.pressure == 1e9


def test_coupler_objections_come_with_every_other_problem(case_file):
    with pytest.raises(CaseError) as info:
        load_case(case_file, ["fluid=none", "coupler=kinematic-splitting", "output.probes[2].quantity=eta",
                              "layers[1].density=-1", "time.dt=0"], FAKES)
    paths = [p.path for p in info.value.problems]
    assert paths == ["time.dt", "layers[1].density", "coupler.model"]
    assert "kinematic-splitting needs a fluid" in str(info.value)


def test_probe_rules(case_file):
    with pytest.raises(CaseError) as info:
        load_case(
            case_file,
            ["output.probes[0].line=2", "output.probes[1].r=0.7", "output.probes[2].r=0.1",
             "output.probes[1].line=0"],
            FAKES,
        )
    assert str(info.value).splitlines() == [
        "output.probes[0].line = 2: expected an interface line 0..1 (0 = lumen) (from --set)",
        "output.probes[1].r = 0.7: expected a radius in [0.5, 0.6] (cm) for d_r (from --set)",
        "output.probes[1].line = 0: d_r takes no line; line applies to eta and v (from --set)",
        "output.probes[2].r = 0.1: flow_rate takes no r; r applies to d_z, d_r, u_z, u_r, p (from --set)",
    ]


def test_duplicate_probe_names(case_file):
    with pytest.raises(CaseError, match=r"output.probes\[1\].name = 'eta_mid': a probe of that name"):
        load_case(case_file, ['output.probes[1].name="eta_mid"'], FAKES)


def test_missing_sections_and_no_wall(tmp_path):
    with pytest.raises(CaseError) as info:
        validate_data({"fluid": "none"}, tmp_path, FAKES)
    assert [p.path for p in info.value.problems] == ["geometry", "mesh", "time", "layers"]
    assert str(info.value).splitlines()[0] == "geometry: missing; expected a [geometry] table with length, radius"


# -- the CLI on invalid cases: exit 2, the key path on stderr, no traceback --------

BASE = textwrap.dedent(
    """\
    title = "wall"

    [geometry]
    length = 6.0
    radius = 0.5

    [mesh]
    nz = 6
    nr = 2
    order = 2

    [time]
    end = 0.001
    dt = 1e-4

    [[layers]]
    model = "koiter-shell"
    density = 1.1
    thickness = 0.02
    young = 7.5e5
    poisson = 0.45

    [[layers]]
    model = "linear-elastic"
    density = 1.2
    thickness = 0.1
    young = 9e5
    poisson = 0.4
    cells = 2

    [loads]
    interface = { model = "cosine-pulse", amplitude = 1.3333e4, duration = 0.003 }

    [initial]
    displacement = { r = "0.001*sin(pi*z/L)" }

    [output]
    every = 0
    probes = [ { name = "eta_mid", quantity = "eta", z = 3.0 }, { name = "dr", quantity = "d_r", z = 3.0, r = 0.55 } ]
    """
)

MISTAKES = [
    # id, (old, new) edit of BASE, extra CLI arguments, what stderr must say
    ("unknown-section", ('title = "wall"', 'title = "wall"\ncolour = "red"'), [], ["colour = 'red': unknown section"]),
    ("layer-key-typo", ("young = 7.5e5", "youngs = 7.5e5"), [], ["layers[0].youngs", "did you mean 'young'?"]),
    ("missing-density", ("density = 1.1\n", ""), [], ["layers[0].density: missing"]),
    ("poisson-half", ("poisson = 0.45", "poisson = 0.5"), [], ["layers[0].poisson = 0.5: expected a number"]),
    ("poisson-below", ("poisson = 0.45", "poisson = -1.2"), [], ["layers[0].poisson = -1.2"]),
    ("density-zero", ("density = 1.2", "density = 0.0"), [], ["layers[1].density = 0.0: expected a number > 0"]),
    ("density-negative", ("density = 1.1", "density = -1.1"), [], ["layers[0].density = -1.1"]),
    ("dt-zero", ("dt = 1e-4", "dt = 0.0"), [], ["time.dt = 0.0: expected a number > 0"]),
    ("dt-negative", ("dt = 1e-4", "dt = -1e-4"), [], ["time.dt = -0.0001"]),
    ("end-not-multiple", ("end = 0.001", "end = 0.00125"), [], ["time.end = 0.00125", "whole number"]),
    ("order-3", ("order = 2", "order = 3"), [], ["mesh.order = 3: expected one of 1, 2"]),
    ("nz-zero", ("nz = 6", "nz = 0"), [], ["mesh.nz = 0: expected an integer >= 1"]),
    ("nz-not-integer", ("nz = 6", "nz = 2.5"), [], ["mesh.nz = 2.5: expected an integer"]),
    ("radius-string", ("radius = 0.5", 'radius = "0.5"'), [], ["geometry.radius = '0.5': expected a number"]),
    ("young-bool", ("young = 9e5", "young = true"), [], ["layers[1].young = true: expected a number"]),
    ("model-misspelt", ('model = "koiter-shell"', 'model = "koiter"'), [],
     ["layers[0].model = 'koiter': no such layer plugin; did you mean 'koiter-shell'?"]),
    ("fluid-misspelt", ("[[layers]]", '[fluid]\nmodel = "navier-stoke"\ndensity = 1.0\n\n[[layers]]'), [],
     ["fluid.model = 'navier-stoke': no such fluid plugin; did you mean 'navier-stokes'?"]),
    ("quantity-misspelt", ('quantity = "eta"', 'quantity = "etaa"'), [],
     ["output.probes[0].quantity = 'etaa'", "did you mean 'eta'?"]),
    ("fluid-probe-no-fluid", ('quantity = "eta"', 'quantity = "p", r = 0.1'), [],
     ["output.probes[0].quantity = 'p': a fluid quantity, but the case has no fluid"]),
    ("probe-outside", ("z = 3.0, r = 0.55", "z = 7.0, r = 0.55"), [], ["output.probes[1].z = 7.0"]),
    ("probe-needs-r", (", r = 0.55", ""), [], ["output.probes[1].r: missing"]),
    ("band-probe-no-band", None, ["--set", 'layers[1]={model="wave-membrane",density=1.2,thickness=0.01,tension=1e3}'],
     ["output.probes[1].quantity = 'd_r': a displacement inside a thick band, but the stack has no thick layer"]),
    ("wall-probe-no-wall", ("[[layers]]", '[fluid]\nmodel = "stokes"\ndensity = 1.0\nviscosity = 0.035\n\n[[layers]]'),
     ["--set", "layers=[]", "--set", "loads.interface=0", "--set", "output.probes[1]={quantity=\"p\", z=3.0, r=0.1}"],
     ["output.probes[0].quantity = 'eta': a wall quantity, but the case has no [[layers]]"]),
    ("cells-on-thin", ("poisson = 0.45", "poisson = 0.45\ncells = 3"), [],
     ["layers[0].cells = 3: only a thick layer has radial cells"]),
    ("formula-name", ("sin(pi*z/L)", "sin(pi*x/L)"), [], ["initial.displacement.r", "unknown name 'x'"]),
    ("load-kind", ('model = "cosine-pulse"', 'model = "cosine_pulse"'), [],
     ["loads.interface.model = 'cosine_pulse'", "did you mean 'cosine-pulse'?"]),
    ("table-missing", ('{ model = "cosine-pulse", amplitude = 1.3333e4, duration = 0.003 }',
                       '{ model = "table", file = "no-such.csv" }'), [],
     ["loads.interface.file = 'no-such.csv': no such file"]),
    ("output-key", ("every = 0", "evry = 0"), [], ["output.evry = 0: unknown key; did you mean 'every'?"]),
    ("solver", ("[output]", '[solver]\nlinear = "umfpak"\n\n[output]'), [], ["solver.linear = 'umfpak'"]),
    ("solver-factors", None, ["--set", "solver.factors=singel"],
     ["solver.factors = 'singel'", "did you mean 'single'?"]),
    ("solver-factorization-cost", None, ["--set", "solver.factorization_cost=0"],
     ["solver.factorization_cost = 0: expected a number > 0.0 (from --set)"]),
    ("missing-geometry", ("[geometry]\nlength = 6.0\nradius = 0.5\n", ""), [], ["geometry: missing"]),
    ("toml-syntax", ("nz = 6", "nz = = 6"), [], ["invalid TOML", "line 8"]),
    ("unused-load", None, ["--set", "loads.inlet=100"],
     ["loads.inlet is set, but structure-only does not apply it (it applies: external, interface)"]),
    ("set-path", None, ["--set", "time.dtt=1e-4"], ["time.dtt = 0.0001: unknown key; did you mean 'dt'? (from --set)"]),
    ("set-index", None, ["--set", "layers[2].young=1e6"], ["layers[2]: no such entry"]),
    ("set-value", None, ["--set", "layers[1].young=-3"], ["layers[1].young = -3: expected a number > 0"]),
    ("set-syntax", None, ["--set", "time.dt"], ["--set = 'time.dt': expected KEY=VALUE"]),
]


# A formula is data: judged on its domain at validation (T = 0.001, L = 6, R = 0.5, H = 0.1 in BASE).
FORMULA_MISTAKES = [
    # id, --set value, what stderr must say
    ("divides-by-zero", 'loads.interface="1/0"',
     ["loads.interface = '1/0': gives inf at t = 0: a division by zero",
      "expected a finite real value for every t in [0, 0.001]"]),
    ("zero-denominator", 'loads.interface="1/(t-t)"', ["loads.interface = '1/(t-t)'", "a division by zero"]),
    ("overflows", 'loads.interface="exp(1000)"', ["loads.interface = 'exp(1000)': gives inf at t = 0: an overflow"]),
    ("not-real", 'loads.interface="sqrt(-1)"', ["loads.interface = 'sqrt(-1)': gives nan", "not a real number"]),
    ("not-real-late", 'loads.interface="1e3*sqrt(0.0005 - t)"',
     ["loads.interface = '1e3*sqrt(0.0005 - t)': gives nan at t = 0.000503906", "not a real number"]),
    ("table-formula", 'loads.interface={model="formula", expr="9**9**9"}',
     ["loads.interface.expr = '9**9**9': gives inf at t = 0: an overflow"]),
    ("power-tower", 'loads.interface="10**10**10*t"', ["loads.interface = '10**10**10*t'", "an overflow"]),
    ("huge-exponent", 'loads.interface="t**5000"', ["loads.interface = 't**5000'", "the exponent 5000 is too large"]),
    ("huge-number", 'loads.interface="1e400*t"', ["loads.interface = '1e400*t'", "too large for a float"]),
    ("too-long", 'loads.interface="' + "t+" * 50_000 + 't"',
     ["loads.interface = 't+t+t+", "too long: 100001 characters; expected at most 2000"]),
    ("too-deep", 'loads.interface="' + "(" * 150 + "t" + ")" * 150 + '"',
     ["loads.interface = '((((", "nested too deeply: 150 levels of brackets; expected at most 100"]),
    ("too-deep-chain", 'initial.velocity.r="' + "-" * 500 + 'z"', ["initial.velocity.r = '----", "nested too deeply"]),
    ("wall-motion-z", 'loads.wall_motion="1/(z-3)"',
     ["loads.wall_motion = '1/(z-3)': gives inf at t = 0, z = 3: a division by zero",
      "for every t in [0, 0.001], z in [0, 6]"]),
    ("initial-r-across-the-band", 'initial.displacement.r="sqrt(0.55 - r)"',
     ["initial.displacement.r = 'sqrt(0.55 - r)': gives nan at z = 0, r = 0.551562", "not a real number",
      "for every z in [0, 6], r in [0.5, 0.6]"]),
    ("initial-constant", 'initial.velocity.z="1/(H - 0.1)"', ["initial.velocity.z = '1/(H - 0.1)'", "a division by zero"]),
]


def assert_refused(path, args, capsys, fragments):
    """``multilayer validate PATH ARGS`` exits 2, names every fragment on stderr, and shows no traceback."""
    assert main(["validate", str(path), *args]) == 2
    out, err = capsys.readouterr()
    for fragment in fragments:
        assert fragment in err
    assert "Traceback" not in out + err


@pytest.mark.parametrize("override, fragments", [m[1:] for m in FORMULA_MISTAKES], ids=[m[0] for m in FORMULA_MISTAKES])
def test_cli_judges_each_formula_on_its_domain(tmp_path, capsys, override, fragments):
    assert_refused(write_case(tmp_path, None), ["--set", override], capsys, fragments)


def test_a_formula_finite_on_its_domain_is_valid(tmp_path, capsys):
    # singular outside [0, T] or across z, r only where the run never evaluates it
    path = write_case(tmp_path, None)
    assert main(["validate", str(path), "--set", 'loads.interface="1/(t + 1e-3)"',
                 "--set", 'initial.displacement.r="1e-3*log(r - 0.4)*sin(pi*z/L)"']) == 0


@pytest.mark.parametrize("expr", ["9**9**9", "10**10**10*t"])
def test_power_towers_are_refused_at_once(tmp_path, expr):
    # as exact integers these never finish: the check runs in a process with a deadline
    path = write_case(tmp_path, None)
    done = subprocess.run([sys.executable, "-m", "multilayer.commands", "validate", str(path),
                           "--set", f'loads.interface="{expr}"'], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "an overflow" in done.stderr and "Traceback" not in done.stderr


# Sizes that cannot run are refused before any work (BASE: a wall of nz x 2 band cells, no fluid).
SIZE_MISTAKES = [
    ("nz-billion", ["mesh.nz=1000000000"],
     ["mesh.nz = 1000000000: the case needs about", "GB of memory (2e+10 unknowns: wall 2e+10), this machine has",
      "GB available"]),
    ("nz-int64-max", ["mesh.nz=9223372036854775807"], ["mesh.nz = 9223372036854775807: the case needs about"]),
    ("cells-billion", ["layers[1].cells=1000000000"], ["layers[1].cells = 1000000000: the case needs about"]),
    ("nr-with-a-fluid", ["fluid={model=\"stokes\", density=1.0, viscosity=0.035}", "coupler=kinematic-splitting",
                         "mesh.nr=1000000000"], ["mesh.nr = 1000000000: the case needs about", "fluid 5.9e+10, wall 130"]),
    ("steps", ["time.dt=1e-13"], ["time.dt = 1e-13: 1e+10 steps to time.end = 0.001; expected at most 1e+08 steps"]),
    ("steps-infinite", ["time.dt=1e-320"], ["time.dt = 1e-320: inf steps"]),
]


@pytest.mark.parametrize("sets, fragments", [m[1:] for m in SIZE_MISTAKES], ids=[m[0] for m in SIZE_MISTAKES])
def test_cli_refuses_sizes_that_cannot_run(tmp_path, capsys, sets, fragments):
    assert_refused(write_case(tmp_path, None), [a for s in sets for a in ("--set", s)], capsys, fragments)


def test_the_memory_check_weighs_the_case_against_this_machine(tmp_path, capsys, monkeypatch):
    import multilayer.case.resources

    path = write_case(tmp_path, None)
    monkeypatch.setattr(multilayer.case.resources, "available_memory", lambda: 1e9)
    assert main(["validate", str(path), "--set", "mesh.nz=20000"]) == 2
    assert ("mesh.nz = 20000: the case needs about 4.6 GB of memory (4e+05 unknowns: wall 4e+05), "
            "this machine has 1 GB available") in capsys.readouterr().err
    monkeypatch.setattr(multilayer.case.resources, "available_memory", lambda: 1e12)
    assert main(["validate", str(path), "--set", "mesh.nz=20000"]) == 0
    monkeypatch.setattr(multilayer.case.resources, "available_memory", lambda: None)  # unknown: not refused
    assert main(["validate", str(path), "--set", "mesh.nz=20000"]) == 0


def write_case(tmp_path, edit):
    text = BASE
    if edit is not None:
        old, new = edit
        assert old in text, old
        text = text.replace(old, new, 1)
    path = tmp_path / "case.toml"
    path.write_text(text)
    return path


def test_the_base_case_is_valid(tmp_path, capsys):
    assert main(["validate", str(write_case(tmp_path, None))]) == 0
    assert "valid" in capsys.readouterr().out


@pytest.mark.parametrize("edit, args, fragments", [m[1:] for m in MISTAKES], ids=[m[0] for m in MISTAKES])
def test_cli_reports_each_mistake(tmp_path, capsys, edit, args, fragments):
    assert_refused(write_case(tmp_path, edit), args, capsys, fragments)


# Other problems and the coupler's objections in one pass (real plugins; BASE is a wall, structure-only).
ONE_PASS = [
    ("load-and-parameter", ["loads.inlet=100", "layers[0].poisson=0.5"],
     ["layers[0].poisson = 0.5: expected a number",
      "coupler.model = 'structure-only': loads.inlet is set, but structure-only does not apply it"]),
    ("fluid-misspelt", ['fluid={model="navier-stoke", density=1.0}', "coupler=structure-only"],
     ["fluid.model = 'navier-stoke': no such fluid plugin",
      "coupler.model = 'structure-only': structure-only runs a wall without fluid"]),
    # monolithic and Dirichlet–Neumann take a thick first layer (issue 24); the kinematic splitting does not
    ("mesh-and-thick-first", ['fluid={model="stokes", density=1.0, viscosity=0.035}', "coupler=kinematic-splitting",
                              "loads.interface=0", "mesh.order=3",
                              'layers[0]={model="linear-elastic", density=1.0, thickness=0.1, young=1e6, poisson=0.3}'],
     ["mesh.order = 3: expected one of 1, 2", "coupler.model = 'kinematic-splitting': kinematic-splitting needs a "
      "thin layer at the fluid interface, but layers[0] is 'linear-elastic' (thick)"]),
]


@pytest.mark.parametrize("sets, fragments", [m[1:] for m in ONE_PASS], ids=[m[0] for m in ONE_PASS])
def test_cli_reports_coupler_objections_with_the_rest(tmp_path, capsys, sets, fragments):
    assert_refused(write_case(tmp_path, None), [a for s in sets for a in ("--set", s)], capsys, fragments)


def test_a_coupler_is_not_asked_about_parts_that_could_not_be_built(tmp_path, capsys):
    # kinematic-splitting reads layers[0]; it is invalid, so the coupler's view of it waits for the next pass
    path = write_case(tmp_path, None)
    assert main(["validate", str(path), "--set", 'fluid={model="stokes", density=1.0, viscosity=0.035}',
                 "--set", "coupler=kinematic-splitting", "--set", "loads.interface=0",
                 "--set", "layers[0].model=koiter"]) == 2
    err = capsys.readouterr().err
    assert "layers[0].model = 'koiter': no such layer plugin" in err
    assert "coupler.model" not in err and "Traceback" not in err


def test_cli_missing_case_file(tmp_path, capsys):
    assert main(["validate", str(tmp_path / "nowhere.toml")]) == 2
    assert "nowhere.toml: no such case file" in capsys.readouterr().err


def test_cli_cross_field_constraint_of_a_real_plugin(tmp_path, capsys):
    path = write_case(tmp_path, ("young = 7.5e5", "young = 7.5e5\nC0 = 1e4"))
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert "layers[0]: koiter-shell:" in err and "C0" in err


def test_console_entry_point_exits_2_without_traceback(tmp_path):
    path = write_case(tmp_path, ("poisson = 0.45", "poisson = 0.5"))
    done = subprocess.run([sys.executable, "-m", "multilayer.commands", "validate", str(path)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert "layers[0].poisson = 0.5" in done.stderr and "Traceback" not in done.stderr + done.stdout


def test_initial_formulas_evaluate_on_arrays(tmp_path):
    case = load_case(write_case(tmp_path, None))
    z = np.linspace(0.0, 6.0, 7)
    np.testing.assert_allclose(case.initial.displacement_r(z=z, r=0.5), 0.001 * np.sin(np.pi * z / 6.0))


def test_the_example_of_the_docs_is_a_valid_case(tmp_path):
    docs = Path(__file__).parents[1] / "docs" / "case-files.md"
    example = docs.read_text().split("```toml\n", 1)[1].split("```", 1)[0]
    case = validate_data(tomllib.loads(example), tmp_path, FAKES)
    assert [layer.model for layer in case.layers] == ["koiter-shell", "linear-elastic"]
    assert [p.name for p in case.output.probes] == ["eta_mid", "dr_mid", "q_out"]
