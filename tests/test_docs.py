"""Documentation that is part of the contract: hooks documented, plugin doctests run."""

import doctest
import importlib
import pkgutil

import pytest

import multilayer_plugins
from multilayer.plugin import hookspecs
from multilayer.plugin.registry import HOOKS, Registry

PLUGIN_MODULES = sorted(m.name for m in pkgutil.walk_packages(multilayer_plugins.__path__, prefix="multilayer_plugins."))


@pytest.mark.parametrize("name", sorted(HOOKS.values()))
def test_every_hook_has_a_docstring_with_an_example(name):
    doc = getattr(hookspecs, name).__doc__
    assert doc and ">>>" in doc


def test_every_hook_is_in_the_plugin_docs():
    from pathlib import Path
    text = (Path(__file__).parents[1] / "docs" / "plugins.md").read_text()
    for name in HOOKS.values():
        assert name in text, name


@pytest.mark.parametrize("module", PLUGIN_MODULES)
def test_plugin_module_doctests(module):
    mod = importlib.import_module(module)
    result = doctest.testmod(mod, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0


def test_every_registered_plugin_has_a_doc_line_and_documented_params():
    for reg in Registry.load().all():
        assert reg.record.doc.strip(), reg.name
        assert "\n" not in reg.record.doc.strip(), reg.name
        for p in reg.record.params:
            assert p.doc, f"{reg.name}.{p.name}"
