"""Hostile inputs (issue 21): each ends at exit 2 with its key path on stderr, no traceback, no hang.

Classes: nesting and size of case files and of ``--set``/``--vary`` values;
probes named like columns of series.csv; integers of the core schemas
without bounds; files that are not regular files (FIFO, device, directory)
or too large; table times out of range; plugins that exit at import;
factories that return the wrong type; an initial displacement that closes
the channel.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from test_casefile import BASE as CASEFILE_BASE

import multilayer.plugin.registry
from multilayer.case.contracts import COUPLER_METHODS
from multilayer.case.files import MAX_CASE_BYTES, MAX_DEPTH, MAX_TABLE_BYTES
from multilayer.case.keys import parse_value, parse_vary
from multilayer.commands.main import main
from multilayer.coupling.contract import Coupler
from multilayer.plugin.problems import CaseError
from multilayer.plugin.registry import Registry

#: test_casefile's valid case, its interface load a table (the file and table inputs are what is tested here)
BASE = CASEFILE_BASE.replace('interface = { model = "cosine-pulse", amplitude = 1.3333e4, duration = 0.003 }',
                             'interface = { model = "table", file = "p.csv" }')
assert 'file = "p.csv"' in BASE
TABLE = "t,p\n0,0\n0.0005,100\n0.001,0\n"


def write(tmp_path, text=BASE, table=TABLE):
    (tmp_path / "p.csv").write_text(table)
    path = tmp_path / "case.toml"
    path.write_text(text)
    return path


def refused(args, capsys, fragments):
    """``multilayer ARGS`` exits 2, names every fragment on stderr, and shows no traceback."""
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    assert code == 2, err
    for fragment in fragments:
        assert fragment in err, err
    assert "Traceback" not in out + err


def sets(*items):
    return [a for item in items for a in ("--set", item)]


def test_the_base_case_is_valid(tmp_path, capsys):
    assert main(["validate", str(write(tmp_path))]) == 0, capsys.readouterr().err


# -- 1. nesting and size, bounded before parsing ----------------------------------------------------

DEEP = 500
NESTED_FILES = [
    ("arrays-500", f"\n[sweep]\nx = {'[' * DEEP}1{']' * DEEP}\n", ["case.toml: arrays or inline tables nested more than"]),
    ("inline-tables-500", f"\n[sweep]\nx = {'{a = ' * DEEP}1{'}' * DEEP}\n", ["nested more than 32 levels deep"]),
    ("mixed-500", f"\n[sweep]\nx = {'[{a = ' * (DEEP // 2)}1{'}]' * (DEEP // 2)}\n", ["nested more than 32"]),
    ("arrays-33", f"\n[sweep]\nx = {'[' * (MAX_DEPTH + 1)}1{']' * (MAX_DEPTH + 1)}\n", ["nested more than 32"]),
    ("arrays-5000", f"\n[sweep]\nx = {'[' * 5000}{']' * 5000}\n", ["nested more than 32"]),
    ("dotted-keys-1000", "\n[solver]\n" + ".".join(["a"] * 1000) + " = 1\n",
     ["solver.a.a.a", "tables or arrays nested more than 32 levels deep"]),
    ("dotted-keys-in-coupler", "\n[coupler]\n" + ".".join(["b"] * 40) + " = 1\n", ["coupler.b.b", "nested more than"]),
    ("table-header-1000", "\n[" + ".".join(["deep"] * 1000) + "]\nx = 1\n", ["deep.deep.deep", "nested more than"]),
    ("array-of-tables-header", "\n[[" + ".".join(["aot"] * 100) + "]]\nx = 1\n", ["aot.aot", "nested more than"]),
    ("inline-dotted", "\n[sweep]\nx = {" + ".".join(["c"] * 100) + " = 1}\n", ["sweep.x.c.c", "nested more than"]),
]


@pytest.mark.parametrize("tail, fragments", [m[1:] for m in NESTED_FILES], ids=[m[0] for m in NESTED_FILES])
def test_deeply_nested_case_files(tmp_path, capsys, tail, fragments):
    refused(["validate", write(tmp_path, BASE + tail)], capsys, fragments)


def test_brackets_inside_strings_and_comments_do_not_count(tmp_path, capsys):
    text = BASE.replace('title = "wall"', 'title = "' + "[{" * 100 + '"  # ' + "[" * 100 + "\n"
                        + "# '''" + "[" * 100 + "\n")
    assert main(["validate", str(write(tmp_path, text))]) == 0, capsys.readouterr().err


def test_a_case_file_over_the_size_cap(tmp_path, capsys):
    text = BASE + "#" * (MAX_CASE_BYTES + 10) + "\n"
    refused(["validate", write(tmp_path, text)], capsys, ["case.toml: 1 MB; expected a case file of at most 1 MB"])


NESTED_SETS = [
    ("set-arrays-500", ["title=" + "[" * DEEP + "]" * DEEP], ["title = '[[[[", "nested more than 32 levels deep",
                                                               "(from --set)"]),
    ("set-inline-500", ["layers[0].young=" + "{a=" * DEEP + "1" + "}" * DEEP], ["layers[0].young = '{a={a=",
                                                                               "nested more than 32"]),
    ("set-key-1000-steps", [".".join(["k"] * 1000) + "=1"], ["a key path of 1000 steps; expected at most 32"]),
    ("set-unbalanced-deep", ["title=" + "[" * DEEP], ["title = '[[[", "nested more than 32"]),
]


@pytest.mark.parametrize("items, fragments", [m[1:] for m in NESTED_SETS], ids=[m[0] for m in NESTED_SETS])
def test_deeply_nested_set_values(tmp_path, capsys, items, fragments):
    refused(["validate", write(tmp_path), *sets(*items)], capsys, fragments)


def test_deeply_nested_vary_values(tmp_path, capsys):
    with pytest.raises(CaseError, match=r"layers\[0\].young = .*nested more than 32 levels deep.*--vary"):
        parse_vary("layers[0].young=1e6," + "[" * DEEP + "]" * DEEP)
    refused(["compare", write(tmp_path), "--vary", "layers[0].young=1e6," + "[" * DEEP + "]" * DEEP,
             "--out", tmp_path / "out"], capsys, ["layers[0].young", "nested more than 32"])
    assert parse_value("[" * DEEP + "]" * DEEP) == "[" * DEEP + "]" * DEEP  # left a string: never parsed


# -- 2. probes named like a column of series.csv ----------------------------------------------------

RESERVED = ["t", "step", "iterations", "energy.total", "energy.residual", "energy.relative_residual",
            "energy.relative_residual.A1", "kinetic.layers[0]", "elastic.layers[1]", "work.external", "work.inlet",
            "dissipation.viscous.fluid", "end.inlet.Q", "stored.outlet", "interface.residual"]


@pytest.mark.parametrize("name", RESERVED)
def test_probe_named_like_a_column(tmp_path, capsys, name):
    refused(["validate", write(tmp_path), *sets(f'output.probes[0].name="{name}"')], capsys,
            [f"output.probes[0].name = '{name}': a column series.csv has already", "eta_z3"])


def test_names_near_the_reserved_ones_are_free(tmp_path, capsys):
    for name in ("energy", "time", "t_mid", "work"):
        assert main(["validate", str(write(tmp_path)), *sets(f'output.probes[0].name="{name}"')]) == 0


# -- 3. integers of the core schemas, bounded ------------------------------------------------------

INTEGERS = [
    ("max-iterations-1e12", "solver.max_iterations=1000000000000", "solver.max_iterations = 1000000000000"),
    ("max-iterations-1001", "solver.max_iterations=1001", "expected an integer >= 1 and <= 1000"),
    ("threads-2-70", f"solver.threads={2 ** 70}", f"solver.threads = {2 ** 70}: expected an integer >= 0 and <= 1024"),
    ("threads-int64", "solver.threads=9223372036854775807", "solver.threads = 9223372036854775807"),
    ("threads-1025", "solver.threads=1025", "solver.threads = 1025"),
    ("every-1e9", "output.every=1000000000", "output.every = 1000000000: expected an integer >= 0 and <= 100000000"),
    ("every-int64", "output.every=9223372036854775807", "output.every = 9223372036854775807"),
    ("probe-line-huge", "output.probes[0].line=1000000000000", "output.probes[0].line = 1000000000000"),
]


@pytest.mark.parametrize("item, fragment", [m[1:] for m in INTEGERS], ids=[m[0] for m in INTEGERS])
def test_unbounded_integers(tmp_path, capsys, item, fragment):
    refused(["validate", write(tmp_path), *sets(item)], capsys, [fragment])


# -- 4. files that are not regular files, or too large ---------------------------------------------

def test_a_directory_as_the_case_file(tmp_path, capsys):
    refused(["validate", tmp_path], capsys, [f"{tmp_path}: a directory, not a regular file; expected a case file"])


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/null", "/dev/urandom"])
def test_a_device_as_the_case_file(capsys, device):
    if not os.path.exists(device):
        pytest.skip(f"no {device}")
    refused(["validate", device], capsys, [f"{device}: a device, not a regular file; expected a case file"])


def test_a_symlink_to_a_device_as_the_case_file(tmp_path, capsys):
    (tmp_path / "zero.toml").symlink_to("/dev/zero")
    refused(["validate", tmp_path / "zero.toml"], capsys, ["zero.toml: a device, not a regular file"])


def test_a_case_file_that_is_not_utf8(tmp_path, capsys):
    path = tmp_path / "case.toml"
    path.write_bytes(b'title = "\xff\xfe"\n')
    refused(["validate", path], capsys, ["case.toml: cannot read the case file", "utf-8"])


def _in_a_process(args, cwd):
    return subprocess.run([sys.executable, "-m", "multilayer.commands", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=20)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_as_the_case_file_or_a_table_does_not_hang(tmp_path):
    os.mkfifo(tmp_path / "fifo.toml")
    os.mkfifo(tmp_path / "fifo.csv")
    write(tmp_path, BASE.replace('file = "p.csv"', 'file = "fifo.csv"'))
    done = _in_a_process(["validate", tmp_path / "fifo.toml"], tmp_path)  # a hang: TimeoutExpired
    assert done.returncode == 2 and "fifo.toml: a FIFO (named pipe), not a regular file" in done.stderr
    assert "Traceback" not in done.stderr
    done = _in_a_process(["validate", tmp_path / "case.toml"], tmp_path)
    assert done.returncode == 2, done.stderr
    assert "loads.interface.file = 'fifo.csv': a FIFO (named pipe), not a regular file; expected a table file" \
           in done.stderr and "Traceback" not in done.stderr


TABLE_FILES = [
    ("directory", lambda d: (d / "t").mkdir(), "t", "loads.interface.file = 't': a directory, not a regular file"),
    ("dev-zero", lambda d: None, "/dev/zero", "loads.interface.file = '/dev/zero': a device, not a regular file"),
    ("symlink-dev-zero", lambda d: (d / "z.csv").symlink_to("/dev/zero"), "z.csv",
     "loads.interface.file = 'z.csv': a device"),
    ("too-large", lambda d: os.truncate(_touch(d / "big.csv"), MAX_TABLE_BYTES + 1), "big.csv",
     "loads.interface.file = 'big.csv': 10 MB; expected a table file of at most 10 MB"),
    ("not-utf8", lambda d: (d / "b.csv").write_bytes(b"t,p\n0,\xff\n"), "b.csv",
     "loads.interface.file = 'b.csv': invalid table"),
]


def _touch(path):
    path.write_text("")
    return path


@pytest.mark.parametrize("make, name, fragment", [m[1:] for m in TABLE_FILES], ids=[m[0] for m in TABLE_FILES])
def test_table_files_that_are_not_tables(tmp_path, capsys, make, name, fragment):
    make(tmp_path)
    refused(["validate", write(tmp_path, BASE.replace('file = "p.csv"', f'file = "{name}"'))], capsys, [fragment])


# -- 5. table times and values within range --------------------------------------------------------

TABLES = [
    ("times-1e308", "t,p\n0,0\n1e308,100\n", "line 3: the time 1e+308 s is outside [-1e+09, 1e+09] s"),
    ("times-pm-1e308", "t,p\n-1e308,0\n1e308,100\n", "line 2: the time -1e+308 s is outside"),
    ("times-1e10", "0,0\n1e10,1\n", "line 2: the time 1e+10 s is outside"),
    ("time-inf", "0,0\ninf,1\n", "line 2: every t and p must be a finite number"),
    ("time-nan", "nan,0\n1,1\n", "line 1: every t and p must be a finite number"),
    ("time-decreasing", "0,0\n1,1\n0.5,2\n", "line 3: the times t must increase strictly"),
    ("p-1e308-integral", "0,1e308\n1e9,1e308\n", "their integral over the table, overflow"),
]


@pytest.mark.parametrize("table, fragment", [m[1:] for m in TABLES], ids=[m[0] for m in TABLES])
def test_tables_out_of_range(tmp_path, capsys, table, fragment):
    refused(["validate", write(tmp_path, table=table)], capsys, ["loads.interface.file = 'p.csv'", fragment])


def test_a_scale_that_overflows_the_table(tmp_path, capsys):
    refused(["validate", write(tmp_path, table="0,0\n1,1e300\n"), *sets('loads.interface.scale=1e10')], capsys,
            ["loads.interface.scale = 10000000000.0: scale × p overflows for p = 1e+300 in p.csv"])


def test_a_period_beyond_range(tmp_path, capsys):
    refused(["validate", write(tmp_path), *sets('loads.interface.period=1e308')], capsys,
            ["loads.interface.period = 1e+308: expected a number > 0.0 and <= 1000000000.0 (s)"])


# -- 6. plugins that exit or are interrupted at import ---------------------------------------------

EXITS = [
    ("sys-exit-0", "import sys\nsys.exit(0)\n", "SystemExit: the module called sys.exit(0) while imported"),
    ("sys-exit-3", "import sys\nsys.exit(3)\n", "sys.exit(3)"),
    ("sys-exit-message", "import sys\nsys.exit('licence expired')\n", "sys.exit('licence expired')"),
    ("raise-system-exit", "raise SystemExit\n", "sys.exit()"),
    ("keyboard-interrupt", "raise KeyboardInterrupt\n", "KeyboardInterrupt: raised by the module while imported"),
    ("exit-builtin", "exit(4)\n", "sys.exit(4)"),
]


@pytest.mark.parametrize("source, fragment", [m[1:] for m in EXITS], ids=[m[0] for m in EXITS])
def test_a_plugin_file_that_exits_at_import(tmp_path, capsys, source, fragment):
    path = tmp_path / "exiting_plugin.py"
    path.write_text(source)
    refused(["validate", write(tmp_path), "--plugin", path], capsys,
            [f"plugins: --plugin {path}: cannot import it", fragment])


HOOKS_THAT_FAIL = [
    ("sys-exit", "sys.exit(3)", "SystemExit: the hook called sys.exit(3)"),
    ("keyboard-interrupt", "raise KeyboardInterrupt", "KeyboardInterrupt: raised by the hook"),
    ("error", "raise RuntimeError('no licence')", "RuntimeError: no licence"),
]


@pytest.mark.parametrize("body, fragment", [m[1:] for m in HOOKS_THAT_FAIL], ids=[m[0] for m in HOOKS_THAT_FAIL])
def test_a_plugin_whose_hook_fails_when_called(tmp_path, capsys, body, fragment):
    path = tmp_path / "failing_hook.py"
    path.write_text("import sys\nfrom multilayer.plugin.hookspecs import hookimpl\n\n@hookimpl\n"
                    f"def multilayer_layers():\n    {body}\n")
    refused(["validate", write(tmp_path), "--plugin", path], capsys,
            ["plugins: multilayer_layers of package", "failed when called", fragment])


def test_a_plugin_module_that_exits_at_import(tmp_path, capsys, monkeypatch):
    (tmp_path / "exiting_module_x21.py").write_text("import sys\nsys.exit(5)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    refused(["plugins", "--plugin", "exiting_module_x21"], capsys, ["--plugin exiting_module_x21", "sys.exit(5)"])


def test_entry_points_that_exit_at_import_are_skipped_with_a_warning(tmp_path, capsys, monkeypatch):
    info = tmp_path / "exiting_thing-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: exiting-thing\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[multilayer]\nexits = exiting_thing_exits\n"
                                           "interrupts = exiting_thing_interrupts\n")
    (tmp_path / "exiting_thing_exits.py").write_text("import sys\nsys.exit(2)\n")
    (tmp_path / "exiting_thing_interrupts.py").write_text("raise KeyboardInterrupt\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(multilayer.plugin.registry, "_REPORTED", set())
    registry = Registry.load()
    assert {f.name for f in registry.failed} == {"exits", "interrupts"}
    assert registry.get("layer", "koiter-shell").package == "multilayer"
    assert main(["validate", str(write(tmp_path))]) == 0
    err = capsys.readouterr().err
    assert "plugin entry point 'exits' (exiting_thing_exits, from exiting-thing 0.1) failed to load and is " \
           "skipped: SystemExit: the module called sys.exit(2) while imported" in err
    assert "'interrupts'" in err and "KeyboardInterrupt" in err and "Traceback" not in err


# -- 7. factories that return the wrong type -------------------------------------------------------

WRONG = '''\
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import CouplerPlugin, FluidPlugin, GeometryPlugin, LayerPlugin, Param
from multilayer_plugins.linear_elastic import LinearElasticBand

D = Param("density", gt=0.0)


@hookimpl
def multilayer_fluids():
    return [FluidPlugin("none-fluid", lambda density: None, (D,), "None"),
            FluidPlugin("int-fluid", lambda density: 3, (D,), "an int")]


@hookimpl
def multilayer_couplers():
    return [CouplerPlugin("none-coupler", lambda: None, (), "None"),
            CouplerPlugin("str-coupler", lambda: "kinematic-splitting", (), "a name")]


@hookimpl
def multilayer_layers():
    return [LayerPlugin("none-layer", lambda density: None, (D,), "None"),
            LayerPlugin("dict-band", lambda density: {"thickness": 0.1}, (D,), "a dict", thin=False),
            LayerPlugin("thick-as-thin", lambda density: LinearElasticBand(density, 0.1, 1e6, 0.3), (D,), "a band")]


@hookimpl
def multilayer_geometries():
    return [GeometryPlugin("none-geometry", lambda: None, (), "None")]
'''

FACTORIES = [
    ("fluid-none", ['fluid={model="none-fluid", density=1.0}'],
     "fluid: none-fluid: the plugin's factory returned NoneType, not a Fluid"),
    ("fluid-int", ['fluid={model="int-fluid", density=1.0}'], "fluid: int-fluid: the plugin's factory returned int"),
    ("coupler-none", ["coupler=none-coupler"], "coupler: none-coupler: the plugin's factory returned NoneType, "
                                               "not a Coupler (it has no energy, evolve)"),
    ("coupler-str", ["coupler=str-coupler"], "coupler: str-coupler: the plugin's factory returned str, not a Coupler"),
    ("layer-none", ['layers[0]={model="none-layer", density=1.0}'],
     "layers[0]: none-layer: the factory returned NoneType; expected a ThinLayer"),
    ("band-dict", ['layers[1]={model="dict-band", density=1.0}'],
     "layers[1]: dict-band: the factory returned dict; expected a ThickLayer"),
    ("thin-is-thick", ['layers[0]={model="thick-as-thin", density=1.0}'],
     "layers[0]: thick-as-thin: the factory returned a thick layer (LinearElasticBand); expected a ThinLayer"),
    ("geometry-none", ["geometry.model=none-geometry"],
     "geometry.model = 'none-geometry': the plugin's factory returned NoneType, not a Geometry"),
]


def test_a_coupler_is_known_by_the_abstract_methods_of_the_contract():
    assert set(COUPLER_METHODS) == Coupler.__abstractmethods__


@pytest.mark.parametrize("items, fragment", [m[1:] for m in FACTORIES], ids=[m[0] for m in FACTORIES])
def test_factories_that_return_the_wrong_type(tmp_path, capsys, items, fragment):
    plugin = tmp_path / "wrong_types.py"
    plugin.write_text(WRONG)
    refused(["validate", write(tmp_path), "--plugin", plugin, *sets(*items)], capsys, [fragment])


# -- 8. an initial displacement that closes the channel (R = 0.5, max_displacement 0.5 R) -----------

CLOSING = [
    ("constant-minus-R", ['initial.displacement.r="-0.5"'], [],
     "initial.displacement.r = '-0.5': gives η = -0.5 cm at z = 0.5 cm on the lumen (r = R = 0.5 cm): R + η ≤ 0 "
     "closes the channel"),
    ("sine-collapse", ['initial.displacement.r="-0.6*sin(pi*z/L)"'], [], "gives η = -0.6 cm at z = 3 cm"),
    ("collapse-with-a-loose-limit", ['initial.displacement.r="-R*(1 + z/L)"', "solver.max_displacement=5"], [],
     "R + η ≤ 0 closes the channel"),
    ("beyond-limit-inward", ['initial.displacement.r="-0.3*sin(pi*z/L)"'], [],
     "gives |η| = 0.3 cm at z = 3 cm on the lumen, more than [solver] max_displacement = 0.5 R = 0.25 cm"),
    ("beyond-limit-outward", ['initial.displacement.r="0.3"'], [], "gives |η| = 0.3 cm"),
    ("beyond-a-tight-limit", ['initial.displacement.r="0.01*sin(pi*z/L)"', "solver.max_displacement=0.01"], [],
     "more than [solver] max_displacement = 0.01 R = 0.005 cm"),
    ("r-dependent", ['initial.displacement.r="-2*r*sin(pi*z/L)"'], [], "R + η ≤ 0 closes the channel"),
]


@pytest.mark.parametrize("items, extra, fragment", [m[1:] for m in CLOSING], ids=[m[0] for m in CLOSING])
def test_initial_displacement_that_closes_the_channel(tmp_path, capsys, items, extra, fragment):
    refused(["validate", write(tmp_path), *sets(*items), *extra], capsys, [fragment])


def test_an_initial_displacement_within_the_limits_is_valid(tmp_path, capsys):
    # at the ends the layers hold it at zero: only the lumen's interior nodes count
    ok = ['initial.displacement.r="0.2*sin(pi*z/L)"', 'initial.displacement.r="-0.24*sin(pi*z/L)"']
    for item in ok:
        assert main(["validate", str(write(tmp_path)), *sets(item)]) == 0, capsys.readouterr().err
