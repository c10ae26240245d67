import csv
import json
import textwrap
import types
from pathlib import Path

import pytest

from multilayer.commands.main import main
from multilayer.runner import loop

WALL = textwrap.dedent(
    """\
    [geometry]
    length = 6.0
    radius = 0.5

    [mesh]
    nz = 6
    nr = 2
    order = 1

    [time]
    end = 5e-4
    dt = 1e-4

    [[layers]]
    model = "{model}"
    density = 1.1
    {params}

    [loads]
    interface = 1000.0

    [output]
    every = 2
    probes = [ {{ name = "eta_mid", quantity = "eta", z = 3.0 }} ]
    """
)
SHELL = WALL.format(model="koiter-shell", params="thickness = 0.1\nyoung = 7.5e5\npoisson = 0.45")
SPRING = WALL.format(model="test-spring", params="stiffness = 1e5")

# The complete plugin of docs/plugins.md: a thin layer on an elastic foundation.
DOCS = Path(__file__).parents[1] / "docs" / "plugins.md"
SPRING_PLUGIN = next(block.split("```", 1)[0] for block in DOCS.read_text().split("```python\n")[1:]
                     if "class Spring" in block)


@pytest.fixture
def spring(tmp_path):
    path = tmp_path / "spring_plugin.py"
    path.write_text(SPRING_PLUGIN)
    return path


def write(tmp_path, text, name="case.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_plugins_table(capsys):
    assert main(["plugins"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split() == ["kind", "name", "package", "version", "doc"]
    rows = {tuple(line.split()[:3]) for line in lines[1:]}
    for name in ("wave-membrane", "koiter-shell", "linear-elastic"):
        assert ("layer", name, "multilayer") in rows
    assert ("coupler", "structure-only", "multilayer") in rows


def test_plugin_parameters(capsys):
    assert main(["plugins", "linear-elastic"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("layer linear-elastic (multilayer")
    assert any(line.split()[:3] == ["thickness", "cm", "required"] for line in out.splitlines())


def test_unknown_plugin_name(capsys):
    assert main(["plugins", "koiter"]) == 2
    assert "did you mean 'koiter-shell'?" in capsys.readouterr().err


def test_plugin_from_a_file_is_listed_validated_and_run(tmp_path, spring, capsys):
    assert main(["plugins", "--plugin", str(spring)]) == 0
    assert any(line.split()[:3] == ["layer", "test-spring", "spring_plugin"] for line in capsys.readouterr().out.splitlines())
    case = write(tmp_path, SPRING)
    assert main(["validate", str(case)]) == 2  # not installed: unknown without --plugin
    assert "layers[0].model = 'test-spring': no such layer plugin" in capsys.readouterr().err
    assert main(["validate", str(case), "--plugin", str(spring)]) == 0
    assert main(["run", str(case), "--plugin", str(spring), "--out", str(tmp_path / "out")]) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["steps"] == 5


def test_plugin_by_module_name_from_the_current_folder(tmp_path, monkeypatch, capsys):
    (tmp_path / "cli_test_spring_module.py").write_text(SPRING_PLUGIN)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr("sys.path", [p for p in __import__("sys").path if p not in ("", str(tmp_path))])
    assert main(["plugins", "test-spring", "--plugin", "cli_test_spring_module"]) == 0
    assert "stiffness" in capsys.readouterr().out


@pytest.mark.parametrize(
    "plugin, words",
    [("no_such_plugin_module", "--plugin no_such_plugin_module: cannot import it (ModuleNotFoundError"),
     ("missing.py", "--plugin missing.py: cannot import it")],
)
def test_plugin_that_cannot_be_imported(plugin, words, capsys):
    assert main(["plugins", "--plugin", plugin]) == 2
    out, err = capsys.readouterr()
    assert words in err and "Traceback" not in out + err


def test_plugin_claiming_a_taken_name(tmp_path, capsys):
    path = tmp_path / "clash.py"
    path.write_text(SPRING_PLUGIN.replace('"test-spring"', '"koiter-shell"'))
    assert main(["validate", str(write(tmp_path, SHELL)), "--plugin", str(path)]) == 2
    assert "two plugins claim the layer name 'koiter-shell'" in capsys.readouterr().err


def test_validate_prints_a_summary(tmp_path, capsys):
    assert main(["validate", str(write(tmp_path, SHELL)), "--set", "time.dt=5e-5"]) == 0
    out = capsys.readouterr().out
    assert "valid" in out and "10 steps of 5e-05 s" in out and "koiter-shell (thin)" in out and "digest" in out


def test_run_a_wall_without_fluid(tmp_path, capsys):
    out = tmp_path / "results"
    assert main(["run", str(write(tmp_path, SHELL)), "--out", str(out)]) == 0
    with open(out / "series.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["step"]) for r in rows] == [1, 2, 3, 4, 5]
    assert "eta_mid" in rows[0]
    assert json.loads((out / "summary.json").read_text())["status"] == "ok"
    assert (out / "wall.pvd").exists()


def test_run_of_an_invalid_case_writes_nothing(tmp_path, capsys):
    out = tmp_path / "results"
    case = write(tmp_path, SHELL)
    assert main(["run", str(case), "--out", str(out), "--set", "layers[0].poisson=0.5"]) == 2
    assert "layers[0].poisson = 0.5" in capsys.readouterr().err
    assert not out.exists()


def test_failed_run_exits_1(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(loop, "run_case",
                        lambda case, out, registry, **kw: types.SimpleNamespace(status="failed", reason="wall collapse",
                                                                                steps=0, t=0.0, peaks={},
                                                                                max_relative_residual=0.0,
                                                                                volume_drift=None))
    assert main(["run", str(write(tmp_path, SHELL)), "--out", str(tmp_path / "o")]) == 1
    assert "run failed: wall collapse" in capsys.readouterr().err


def test_crashed_run_exits_1(tmp_path, monkeypatch, capsys):
    def crash(case, out, registry, **kw):
        raise ZeroDivisionError("boom")

    monkeypatch.setattr(loop, "run_case", crash)
    assert main(["run", str(write(tmp_path, SHELL)), "--out", str(tmp_path / "o")]) == 1
    assert "ZeroDivisionError: boom" in capsys.readouterr().err


def test_usage_errors_exit_2(capsys):
    with pytest.raises(SystemExit) as info:
        main([])
    assert info.value.code == 2
    with pytest.raises(SystemExit) as info:
        main(["run", "case.toml"])  # --out is required
    assert info.value.code == 2
