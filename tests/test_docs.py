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


def _anchor(heading: str) -> str:
    """The anchor GitHub gives a Markdown heading: lower case, punctuation dropped, spaces to hyphens."""
    import re
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def _anchors(path):
    import re
    found, fenced = set(), False
    for line in path.read_text().splitlines():
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and re.match(r"#{1,6} ", line):
            found.add(_anchor(line.lstrip("#")))
    return found


def test_every_relative_link_of_the_docs_reaches_its_file_and_heading():
    """A page moved or a heading renamed breaks the links to it: every relative link of docs/*.md and the README
    names a file that exists and, after '#', a heading of that file."""
    import re
    from pathlib import Path
    root = Path(__file__).parents[1]
    broken = []
    for page in sorted([*root.glob("docs/*.md"), root / "README.md"]):
        for target in re.findall(r"\]\(([^)\s]+)\)", page.read_text()):
            if target.startswith(("http://", "https://", "mailto:")):
                continue
            name, _, anchor = target.partition("#")
            linked = (page.parent / name) if name else page
            if not linked.exists():
                broken.append(f"{page.name}: {target} (no such file)")
            elif anchor and linked.suffix == ".md" and anchor not in _anchors(linked):
                broken.append(f"{page.name}: {target} (no such heading)")
    assert not broken, "\n".join(broken)
