"""An installed plugin that fails to load is reported once and skipped: it breaks nothing else."""

import subprocess
import sys
from pathlib import Path

import pytest

import multilayer.plugin.registry
from multilayer.commands.main import main
from multilayer.plugin.registry import Registry

CASES = Path(__file__).parents[1] / "cases"

ENTRY_POINTS = """\
[multilayer]
broken-import = broken_thing_missing_module
broken-raises = broken_thing_raises
broken-hooks = broken_thing_hooks
"""


@pytest.fixture
def site(tmp_path, monkeypatch):
    """A folder on sys.path holding an installed distribution whose three plugins cannot be loaded."""
    info = tmp_path / "broken_thing-0.3.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-thing\nVersion: 0.3\n")
    (info / "entry_points.txt").write_text(ENTRY_POINTS)
    (tmp_path / "broken_thing_raises.py").write_text('raise RuntimeError("needs a licence key")\n')
    (tmp_path / "broken_thing_hooks.py").write_text(
        "from multilayer.plugin.hookspecs import hookimpl\n\n@hookimpl\ndef multilayer_layer():\n    return []\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(multilayer.plugin.registry, "_REPORTED", set())
    return tmp_path


def test_each_failing_entry_point_is_skipped_and_reported_once(site, capsys):
    registry = Registry.load()
    assert {f.name for f in registry.failed} == {"broken-import", "broken-raises", "broken-hooks"}
    assert registry.get("layer", "koiter-shell").package == "multilayer"  # the rest is there
    Registry.load()  # a second load in the same process says nothing again
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 3
    assert ("multilayer: warning: plugin entry point 'broken-import' (broken_thing_missing_module, from "
            "broken-thing 0.3) failed to load and is skipped: ModuleNotFoundError: No module named "
            "'broken_thing_missing_module'") in lines
    assert any("'broken-raises'" in line and "RuntimeError: needs a licence key" in line for line in lines)
    assert any("'broken-hooks'" in line and "PluginValidationError" in line and "multilayer_layer" in line
               for line in lines)


def test_commands_work_for_cases_that_do_not_use_it(site, capsys):
    assert main(["validate", str(CASES / "membrane-mode.toml")]) == 0
    assert main(["plugins"]) == 0
    out, err = capsys.readouterr()
    assert "valid" in out and "wave-membrane" in out
    assert err.count("warning: plugin entry point") == 3


def test_a_case_that_names_a_missing_model_gets_a_note(site, capsys):
    assert main(["validate", str(CASES / "membrane-mode.toml"), "--set", "layers[0].model=broken-layer"]) == 2
    err = capsys.readouterr().err
    assert "layers[0].model = 'broken-layer': no such layer plugin" in err
    assert "note: plugin entry point 'broken-import' (broken_thing_missing_module, from broken-thing 0.3) " \
           "failed to load" in err
    assert "Traceback" not in err


def test_the_console_script_warns_once_and_runs(site):
    import os

    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-m", "multilayer.commands", "plugins", "koiter-shell"], env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "young" in done.stdout
    assert done.stderr.count("warning: plugin entry point") == 3 and "Traceback" not in done.stderr


def test_a_plugin_given_with_the_plugin_option_must_load(tmp_path, capsys):
    path = tmp_path / "typo_hooks.py"
    path.write_text("from multilayer.plugin.hookspecs import hookimpl\n\n@hookimpl\ndef multilayer_layer():\n    return []\n")
    assert main(["plugins", "--plugin", str(path)]) == 2
    err = capsys.readouterr().err
    assert "typo_hooks" in err and "multilayer_layer" in err and "Traceback" not in err
