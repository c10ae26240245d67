"""The conformance kit (multilayer.testing) and `multilayer check-plugin`: every layer passes, each mistake fails."""

from pathlib import Path

import broken_layers
import numpy as np
import pytest

from multilayer.commands.main import main
from multilayer.plugin.loading import import_plugin
from multilayer.plugin.records import LayerPlugin, Param
from multilayer.testing import (
    CHECKS,
    LayerConformance,
    assert_layer_conforms,
    check_layer,
    example_params,
)
from multilayer.wall.stack import WallSpace
from multilayer_plugins.planar import Planar


class TestWaveMembrane(LayerConformance):
    layer = "wave-membrane"


class TestKoiterShell(LayerConformance):
    layer = "koiter-shell"


class TestLinearElastic(LayerConformance):
    layer = "linear-elastic"


class TestLinearElasticSliding(LayerConformance):
    layer = "linear-elastic"
    params = {"density": 1.0, "thickness": 0.2, "lame_mu": 3e5, "lame_lambda": 5e5, "ends": "sliding",
              "faces": "sliding"}


class TestASpringFromATestModule(LayerConformance):
    layer = "good-spring"
    plugins = (broken_layers,)


# every mistake is found by the kit: (name, the words of a failed check)
KIT = ([(m[0], m[3]) for m in broken_layers.MISTAKES] + [(m[0], m[3]) for m in broken_layers.KIT_ONLY]
       + [(m[0], m[2]) for m in broken_layers.SCHEMA_MISTAKES])


@pytest.mark.parametrize("name, words", KIT, ids=[k[0] for k in KIT])
def test_the_kit_finds_each_mistake(tmp_path, name, words):
    results = check_layer(name, plugins=[broken_layers], workdir=tmp_path)
    assert [r.name for r in results] == list(CHECKS)
    assert any(words in "; ".join(r.problems) for r in results if not r.ok), [str(r) for r in results]
    with pytest.raises(AssertionError, match=f"layer '{name}' does not conform"):
        assert_layer_conforms(name, plugins=[broken_layers], workdir=tmp_path)


@pytest.mark.parametrize("name, check, words", [(m[0], m[2], m[3]) for m in broken_layers.KIT_ONLY],
                         ids=[m[0] for m in broken_layers.KIT_ONLY])
def test_the_check_that_finds_it(tmp_path, name, check, words):
    # validation lets these through: only the kit's own check sees them
    (result,) = check_layer(name, plugins=[broken_layers], checks=(check,), workdir=tmp_path)
    assert not result.ok and words in "; ".join(result.problems)


def test_the_test_class_fails_the_check_that_fails():
    class TestBroken(LayerConformance):
        layer = "broken-float-damping"
        plugins = (broken_layers,)

    TestBroken().test_schema()
    TestBroken().test_essential_dofs()
    with pytest.raises(AssertionError, match=r"FAIL  matrices: order 1: damping must be a scipy sparse matrix"):
        TestBroken().test_matrices()


def test_made_up_parameters_lie_inside_the_bounds():
    record = LayerPlugin("x", dict, (Param("density", unit="g/cm³", gt=0.0), Param("poisson", unit="1", gt=-1.0, lt=0.5),
                                     Param("ratio", unit="1", ge=0.0, le=1.0), Param("n", type=int, ge=3),
                                     Param("ends", type=str, default="a", choices=("a", "b")),
                                     Param("mode", type=str, choices=("x", "y"))))
    assert example_params(record) == {"density": 1.0, "poisson": -0.25, "ratio": 0.5, "n": 4, "mode": "x"}
    assert example_params(LayerPlugin("x", dict, (Param("density"),), example={"density": 2.0})) == {"density": 2.0}


def test_an_unknown_check_or_layer():
    with pytest.raises(ValueError, match="no such check 'matrix'"):
        check_layer("wave-membrane", checks=("matrix",))
    with pytest.raises(KeyError, match="did you mean 'koiter-shell'"):
        check_layer("koiter")


# -- the command --------------------------------------------------------------------


@pytest.mark.parametrize("name", ["wave-membrane", "koiter-shell", "neo-hookean-membrane", "hgo-membrane",
                                  "linear-elastic"])
def test_check_plugin_passes_the_built_in_layers(name, capsys):
    assert main(["check-plugin", name]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].startswith(f"check-plugin {name} (multilayer ")
    assert [line.split()[0] for line in out.splitlines()[1:-1]] == ["ok"] * len(CHECKS)
    assert out.splitlines()[-1] == f"all {len(CHECKS)} checks passed"


def test_check_plugin_prints_one_line_per_failed_check(capsys):
    assert main(["check-plugin", "broken-shape", "--plugin", "broken_layers"]) == 1
    out, err = capsys.readouterr()
    failed = [line for line in out.splitlines() if line.startswith("  FAIL")]
    assert failed == [
        "  FAIL  matrices: order 1: mass has shape (6, 6); expected (5, 5) for its space; "
        "order 2: mass has shape (10, 10); expected (9, 9) for its space",
        "  FAIL  coupled-run: the scene is not a valid case: layers[0]: broken-shape: mass has shape (6, 6); "
        "expected (5, 5) for its space",
    ]
    assert out.splitlines()[-1] == f"2 of {len(CHECKS)} checks failed" and "Traceback" not in out + err


def test_check_plugin_takes_parameters(capsys):
    assert main(["check-plugin", "linear-elastic", "--param", "ends=sliding", "--param", "poisson=0.3"]) == 0
    assert main(["check-plugin", "linear-elastic", "--param", "poisson=0.7"]) == 1
    assert "FAIL  build: linear-elastic.poisson = 0.7: expected a number > -1.0 and < 0.5" in capsys.readouterr().out
    assert main(["check-plugin", "linear-elastic", "--param", "poisson"]) == 2
    assert "--param 'poisson': expected KEY=VALUE" in capsys.readouterr().err


@pytest.mark.parametrize("name, words", [("koiter", "no layer plugin named 'koiter'; did you mean 'koiter-shell'?"),
                                         ("stokes", "'stokes' is a fluid plugin; check-plugin checks layer plugins")])
def test_check_plugin_of_an_unknown_name_exits_2(name, words, capsys):
    assert main(["check-plugin", name]) == 2
    assert words in capsys.readouterr().err


# -- the thick layer of docs/plugins.md --------------------------------------------------

DOCS = Path(__file__).parents[1] / "docs" / "plugins.md"
THICK_EXAMPLE = next(block.split("```", 1)[0] for block in DOCS.read_text().split("```python\n")[1:]
                     if "class KelvinVoigtBand" in block)


@pytest.mark.parametrize("params", [[], ["--param", "ends=sliding"]], ids=["clamped", "sliding"])
def test_the_thick_layer_of_the_docs_passes_check_plugin(tmp_path, capsys, params):
    path = tmp_path / "kv_band.py"
    path.write_text(THICK_EXAMPLE)
    assert main(["check-plugin", "kelvin-voigt-band", "--plugin", str(path), *params]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == f"all {len(CHECKS)} checks passed"


def test_sliding_ends_of_the_docs_hold_only_d_z(tmp_path):
    path = tmp_path / "kv_band_module.py"
    path.write_text(THICK_EXAMPLE)
    module = import_plugin(str(path))
    band = module.KelvinVoigtBand(1.1, 0.1, 7.5e5, 0.45, 0.0, "sliding")
    space = WallSpace.build([band], Planar(), 6.0, 0.5, 4, 2, [2]).bands[0]
    held = band.essential_dofs(space)
    z_dofs, r_dofs = space.basis.split_indices()
    ends = np.union1d(space.side_dofs("z=0"), space.side_dofs("z=L"))
    assert np.array_equal(held, np.intersect1d(ends, z_dofs)) and not np.intersect1d(held, r_dofs).size
