"""Plugins are chosen by ``model`` in every table of a case; the old key ``kind`` is a validation error at each place.

Through ``multilayer validate`` and ``multilayer run`` (stderr, exit code 2, nothing run), through the Python API,
and through the pieces that read a plugin's table themselves (a load, a scheme).
"""

import shutil
from pathlib import Path

import pytest

import multilayer as ml
from multilayer.case.spelling import old_model_keys
from multilayer.commands.main import main
from multilayer.commands.plugins import CASE_LINES
from multilayer.functions.loads import load_from_spec
from multilayer.numerics.timescheme import named
from multilayer.plugin.problems import CaseError
from multilayer.plugin.records import MODEL, OLD_MODEL
from multilayer.plugin.registry import HOOKS, Registry

CASES = Path(__file__).parents[1] / "cases"

#: every place of the carotid case where a table names a plugin: the new spelling, and the old one
CAROTID = [('[geometry]\nmodel = "axisymmetric"', '[geometry]\nkind = "axisymmetric"'),
           ('inlet = { model = "flow-rate", flow = { model = "table",',
            'inlet = { kind = "flow-rate", flow = { kind = "table",'),
           ('outlet = { model = "windkessel"', 'outlet = { kind = "windkessel"')]
#: what validation says about the old spelling, in the order of the case
OLD = ["geometry.kind = 'axisymmetric': plugins are chosen by 'model', not 'kind'; write model = \"axisymmetric\"",
       "coupler.scheme.kind = 'bdf2': plugins are chosen by 'model', not 'kind'; write model = \"bdf2\"",
       "loads.inlet.kind = 'flow-rate': plugins are chosen by 'model', not 'kind'; write model = \"flow-rate\"",
       "loads.inlet.flow.kind = 'table': plugins are chosen by 'model', not 'kind'; write model = \"table\"",
       "loads.outlet.kind = 'windkessel': plugins are chosen by 'model', not 'kind'; write model = \"windkessel\""]


def carotid(tmp_path: Path, old: bool, name: str = "carotid.toml") -> Path:
    """The bundled carotid case in ``tmp_path`` (with its flow table), its plugins named the new way or the old."""
    text = (CASES / "carotid.toml").read_text()
    assert "[coupler]" not in text
    for new, before in CAROTID:
        assert new in text, new
        text = text.replace(new, before) if old else text
    text += f'\n[coupler]\nscheme = {{ {OLD_MODEL if old else MODEL} = "bdf2" }}\n'  # a plugin a parameter names
    (tmp_path / "data").mkdir(exist_ok=True)
    shutil.copy(CASES / "data" / "cca-flow-1s.csv", tmp_path / "data")
    path = tmp_path / name
    path.write_text(text)
    return path


def test_validate_names_every_old_key_at_once_with_the_line_to_write(tmp_path, capsys):
    assert main(["validate", str(carotid(tmp_path, old=True))]) == 2
    out = capsys.readouterr()
    lines = out.err.splitlines()
    assert lines[0].endswith("carotid.toml: invalid case") and lines[1:] == OLD, lines
    assert "Traceback" not in out.err and out.out == ""


def test_the_new_spelling_is_the_same_case(tmp_path):
    case = ml.load_case(carotid(tmp_path, old=False))
    assert case.geometry.model == "axisymmetric" and case.coupler.params["scheme"] == {"model": "bdf2"}
    assert case.resolved["loads"]["inlet"]["model"] == "flow-rate"
    assert case.resolved["loads"]["inlet"]["flow"]["model"] == "table"
    assert case.resolved["loads"]["outlet"]["model"] == "windkessel"
    bundled = ml.load_case(CASES / "carotid.toml", {"coupler.scheme": {"model": "bdf2"}})
    assert case.digest == bundled.digest


def test_run_refuses_the_old_key_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", str(carotid(tmp_path, old=True)), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.splitlines()[1:] == OLD and "Traceback" not in err
    assert not out.exists() or not any(out.iterdir())


def test_the_old_key_is_reported_with_the_case_s_other_problems(tmp_path, capsys):
    """Read as the model it names, the old key does not hide the rest of the case, nor add a missing model."""
    assert main(["validate", str(carotid(tmp_path, old=True)), "--set", "mesh.nz=-1", "--set",
                 "loads.outlet.distal=-1.0"]) == 2
    lines = capsys.readouterr().err.splitlines()[1:]
    assert lines[:len(OLD)] == OLD, lines
    assert sorted(lines[len(OLD):]) == [
        "loads.outlet.distal = -1.0: expected a number > 0.0 (dyn·s/cm⁴ per unit depth (planar), dyn·s/cm⁵ (tube)) "
        "(from --set)", "mesh.nz = -1: expected an integer >= 1 (from --set)"], lines


@pytest.mark.parametrize("override, problem", [
    ("geometry.kind=axisymmetric",
     "geometry.kind = 'axisymmetric': plugins are chosen by 'model', not 'kind', and model = 'axisymmetric' is given "
     "too; remove kind (from --set)"),
    ('layers[0]={kind="koiter-shell",density=1.1,thickness=0.03,young=4e6,poisson=0.49}',
     "layers[0].kind = 'koiter-shell': plugins are chosen by 'model', not 'kind'; write model = \"koiter-shell\" "
     "(from --set)"),
    ('fluid={kind="stokes",density=1.06,viscosity=0.035}',
     "fluid.kind = 'stokes': plugins are chosen by 'model', not 'kind'; write model = \"stokes\" (from --set)"),
    ('loads.external={kind="sine",amplitude=10.0,frequency=1.0}',
     "loads.external.kind = 'sine': plugins are chosen by 'model', not 'kind'; write model = \"sine\" (from --set)"),
    ('coupler={kind="monolithic"}',
     "coupler.kind = 'monolithic': plugins are chosen by 'model', not 'kind'; write model = \"monolithic\" "
     "(from --set)"),
])
def test_every_table_that_names_a_plugin_refuses_the_old_key(override, problem, capsys):
    assert main(["validate", str(CASES / "carotid.toml"), "--set", override]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert problem in lines, lines


def test_the_python_api_refuses_the_old_key(tmp_path):
    with pytest.raises(CaseError) as info:
        ml.load_case(carotid(tmp_path, old=True))
    assert [str(p) for p in info.value.problems] == OLD
    with pytest.raises(CaseError, match=r"^geometry.kind = 'planar': plugins are chosen by 'model', not 'kind', and "
                                        r"model = 'axisymmetric' is given too; remove kind \(from --set\)$"):
        ml.load_case(CASES / "carotid.toml", {"geometry.kind": "planar"})
    with pytest.raises(CaseError, match=r"^loads.inlet.kind = 'sine': plugins are chosen by 'model', not 'kind'; "
                                        r"write model = \"sine\"$"):
        load_from_spec({"kind": "sine", "amplitude": 1.0, "frequency": 1.0}, "loads.inlet")
    with pytest.raises(ValueError, match=r"^kind = 'bdf2': plugins are chosen by 'model', not 'kind'; "
                                         r"write model = \"bdf2\"$"):
        Registry.load().build("scheme", {"kind": "bdf2"})
    assert named("bdf2").order == 2


def test_old_model_keys_leaves_the_case_data_as_it_is():
    data = {"geometry": {"kind": "axisymmetric"}, "layers": [{"model": "koiter-shell", "kind": "koiter-shell"}],
            "loads": {"inlet": 0.0, "outlet": {"kind": "resistance", "resistance": 1.0}}}
    fixed, problems = old_model_keys(data)
    assert [p.path for p in problems] == ["geometry.kind", "layers[0].kind", "loads.outlet.kind"]
    assert fixed == {"geometry": {"model": "axisymmetric"}, "layers": [{"model": "koiter-shell"}],
                     "loads": {"inlet": 0.0, "outlet": {"model": "resistance", "resistance": 1.0}}}
    assert data["geometry"] == {"kind": "axisymmetric"} and "kind" in data["layers"][0]


def test_no_plugin_takes_a_parameter_named_model_or_kind():
    """In a table that names a plugin, ``kind`` is never one of its parameters: refusing it takes nothing away."""
    registry = Registry.load()
    assert registry.all()
    clash = [(r.kind, r.name, p.name) for r in registry.all() for p in r.record.params if p.name in (MODEL, OLD_MODEL)]
    assert clash == []


def test_plugins_says_how_a_case_names_each_kind_of_plugin(capsys):
    assert set(CASE_LINES) == set(HOOKS)
    assert main(["plugins", "axisymmetric"]) == 0
    assert 'in a case file: [geometry] model = "axisymmetric"' in capsys.readouterr().out.splitlines()
