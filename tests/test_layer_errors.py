"""A plugin's mistake names the layer and what is wrong: at validation, and when a run starts."""

import json
import textwrap

import attrs
import broken_layers
import pytest

from multilayer.case.casefile import load_case
from multilayer.case.model import LayerSpec
from multilayer.commands.main import main
from multilayer.plugin.registry import Registry
from multilayer.runner.loop import run_case
from multilayer.scene.setup import build_layer
from multilayer.wall.checks import LayerError
from multilayer.wall.stack import Stack, WallSpace
from multilayer_plugins.planar import Planar

REGISTRY = Registry.load(extra=[broken_layers])

CASE = textwrap.dedent(
    """\
    [geometry]
    length = 6.0
    radius = 0.5

    [mesh]
    nz = 6
    nr = 1
    order = 2

    [time]
    end = 3e-4
    dt = 1e-4

    [[layers]]
    model = "{model}"
    density = 1.1

    [initial]
    displacement = {{ r = "0.001*sin(pi*z/L)" }}
    """
)

SEEN = [(name, said) for name, _, said, _ in broken_layers.MISTAKES if said is not None]


@pytest.mark.parametrize("name, said", SEEN, ids=[m[0] for m in SEEN])
def test_validate_names_the_layer_and_the_mistake(tmp_path, capsys, name, said):
    path = tmp_path / "case.toml"
    path.write_text(CASE.format(model=name))
    assert main(["validate", str(path), "--plugin", "broken_layers"]) == 2
    out, err = capsys.readouterr()
    assert f"layers[0]: {name}: {said}" in err
    assert "Traceback" not in out + err


def test_a_good_layer_passes_the_same_checks(tmp_path, capsys):
    path = tmp_path / "case.toml"
    path.write_text(CASE.format(model="good-spring"))
    assert main(["validate", str(path), "--plugin", "broken_layers"]) == 0
    assert main(["run", str(path), "--plugin", "broken_layers", "--out", str(tmp_path / "out")]) == 0


RUN = [(m[0], m[3]) for m in broken_layers.MISTAKES]


@pytest.mark.parametrize("name, said", RUN, ids=[m[0] for m in RUN])
def test_a_run_that_meets_the_mistake_fails_cleanly_naming_the_layer(tmp_path, name, said):
    # the run of a case validated before the layer changed: the wall's assembly names the mistake
    path = tmp_path / "case.toml"
    path.write_text(CASE.format(model="good-spring"))
    case = load_case(path, registry=REGISTRY)
    layer = LayerSpec(path="layers[0]", model=name, params={"density": 1.1, "stiffness": 1e4})
    result = run_case(attrs.evolve(case, layers=(layer,)), tmp_path / "out", REGISTRY)
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert result.status == "failed" and "traceback" not in summary
    assert result.reason.startswith(f"setting up the scene failed: layers[0] ({name}): ")
    assert said in result.reason


@pytest.mark.parametrize("name, said", [(m[0], m[3]) for m in broken_layers.MISTAKES[:8]],
                         ids=[m[0] for m in broken_layers.MISTAKES[:8]])
def test_the_assembly_checks_what_each_layer_returns(name, said):
    spec = LayerSpec(path="layers[1]", model=name, params={"density": 1.0, "stiffness": 1e4})
    good = build_layer(REGISTRY, LayerSpec(path="layers[0]", model="good-spring", params={"density": 1.0}))
    if name == "broken-abstract":
        with pytest.raises(LayerError, match=r"^layers\[1\] \(broken-abstract\): NoForms does not implement forms"):
            build_layer(REGISTRY, spec)
        return
    layer = build_layer(REGISTRY, spec)
    space = WallSpace.build([good, layer], Planar(), 6.0, 0.5, 4, 1, names=["good-spring", name])
    with pytest.raises(LayerError) as info:
        Stack.assemble(space)
    assert str(info.value).startswith(f"layers[1] ({name}): ") and said in str(info.value)


def test_a_factory_that_returns_no_layer_is_named_when_the_run_starts():
    spec = LayerSpec(path="layers[2]", model="broken-not-a-layer", params={"density": 1.0})
    with pytest.raises(LayerError, match=r"^layers\[2\] \(broken-not-a-layer\): the factory returned dict; "
                                         r"expected a ThinLayer \(the plugin is registered with thin=True\)$"):
        build_layer(REGISTRY, spec)
