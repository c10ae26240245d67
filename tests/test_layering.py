"""The house's layering (pyproject.toml, ``[tool.importlinter]``) and the size of its modules, checked in CI."""

import ast
import doctest
import textwrap
from pathlib import Path

from importlinter.cli import lint_imports

ROOT = Path(__file__).parents[1]
#: lines a module of multilayer/ may have at most: past that, split it by subject
MAX_LINES = 600


def test_the_import_contracts_are_kept(capsys):
    code = lint_imports(config_filename=str(ROOT / "pyproject.toml"), no_cache=True, no_logo=True)
    report = capsys.readouterr().out
    assert code == 0, f"lint-imports found a broken contract:\n{report}"


def test_no_module_is_longer_than_the_limit():
    lengths = {path.relative_to(ROOT).as_posix(): len(path.read_text(encoding="utf-8").splitlines())
               for path in (ROOT / "multilayer").rglob("*.py")}
    assert lengths, "no modules found under multilayer/"
    too_long = {name: n for name, n in sorted(lengths.items()) if n > MAX_LINES}
    assert not too_long, f"modules over {MAX_LINES} lines (split them by subject): {too_long}"


def strongly_connected(graph, modules):
    """The import cycles among ``modules``: Tarjan's strongly connected components of more than one module."""
    index, low, stack, on, cycles = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.find_modules_directly_imported_by(v):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while not component or component[-1] != v:
                component.append(stack.pop())
                on.discard(component[-1])
            if len(component) > 1:
                cycles.append(sorted(component))

    for module in sorted(modules):
        if module not in index:
            visit(module)
    return cycles


def test_no_two_modules_import_each_other():
    """Within a layer too: a module's imports (in functions as well) never lead back to it."""
    import grimp

    graph = grimp.build_graph("multilayer")
    assert strongly_connected(graph, graph.modules) == []


def test_the_cycle_finder_finds_a_cycle():
    class Graph:
        edges = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}

        def find_modules_directly_imported_by(self, m):
            return self.edges[m]

    assert strongly_connected(Graph(), Graph.edges) == [["a", "b", "c"]]


# -- doctests of the core: no plugin ---------------------------------------------------------------------------------
# The core's examples show the core: a geometry, a layer, a scheme or a boundary condition they need is a stand-in
# defined in the example (or a registry of stand-ins, Registry.load([...], entry_points=False)), never a built-in
# plugin: the core's doctests pass with multilayer_plugins absent, and a plugin's change never breaks them.


def docstring_examples(root: Path = ROOT / "multilayer"):
    """(file, line, source) of every doctest example of the modules under ``root``, read from their text."""
    parser = doctest.DocTestParser()
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
                doc = ast.get_docstring(node, clean=False)
                if doc and ">>>" in doc:
                    first = node.body[0].lineno if not isinstance(node, ast.Module) else 1
                    for example in parser.get_examples(doc):
                        yield path, first + example.lineno, example.source


def registry_defaults(root: Path = ROOT / "multilayer") -> dict[str, int]:
    """Name → position of its ``registry`` argument, for every function under ``root`` whose ``registry`` defaults
    to None: called without one, it loads the installed plugins."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.FunctionDef):
                continue
            args = node.args
            positional = [*args.posonlyargs, *args.args]
            defaults = dict(zip([a.arg for a in positional][len(positional) - len(args.defaults):], args.defaults))
            defaults |= {a.arg: d for a, d in zip(args.kwonlyargs, args.kw_defaults) if d is not None}
            if isinstance(defaults.get("registry"), ast.Constant) and defaults["registry"].value is None:
                names = [a.arg for a in positional]
                skip = 1 if names and names[0] in ("self", "cls") else 0
                out[node.name] = names.index("registry") - skip if "registry" in names else 10**6
    return out


def plugin_uses(source: str, loaders: dict[str, int]) -> list[str]:
    """What in the doctest example ``source`` needs the installed plugins: an import of ``multilayer_plugins``, a
    ``Registry.load`` of the entry points, a call of a ``loaders`` function without its registry.

    >>> plugin_uses("from multilayer_plugins import planar\\n", {}), plugin_uses("x = 1  # multilayer_plugins\\n", {})
    (['imports multilayer_plugins'], [])
    >>> plugin_uses("importlib.import_module('multilayer_plugins.planar')\\n", {})
    ['imports multilayer_plugins']
    >>> plugin_uses("named('bdf2').order\\n", {"named": 1}), plugin_uses("named('bdf2', reg)\\n", {"named": 1})
    (['named(...) without a registry: the installed plugins'], [])
    >>> plugin_uses("Registry.load().names('x')\\n", {}), plugin_uses("Registry.load([p], entry_points=False)\\n", {})
    (['Registry.load(...) of the installed plugins'], [])
    """
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return ["imports multilayer_plugins"] if "multilayer_plugins" in source else []
    modules = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    modules += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    modules += [n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)]  # by name
    found = ["imports multilayer_plugins"] if any(m.split(".")[0] == "multilayer_plugins" for m in modules) else []
    for call in (n for n in ast.walk(tree) if isinstance(n, ast.Call)):
        func = call.func
        name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
        keywords = {k.arg: k.value for k in call.keywords}
        if name == "load" and isinstance(func, ast.Attribute) and getattr(func.value, "id", "") == "Registry":
            off = keywords.get("entry_points")
            if not (isinstance(off, ast.Constant) and off.value is False):
                found.append("Registry.load(...) of the installed plugins")
        elif name in loaders and "registry" not in keywords and len(call.args) <= loaders[name] and not any(
                isinstance(a, ast.Starred) for a in call.args):
            found.append(f"{name}(...) without a registry: the installed plugins")
    return found


def test_no_doctest_of_the_core_uses_a_plugin():
    loaders = registry_defaults()
    assert {"named", "schemes", "load_case", "validate_data"} <= set(loaders), sorted(loaders)
    examples = list(docstring_examples())
    assert len(examples) > 100, len(examples)
    offenders = [f"{path.relative_to(ROOT)}:{line}: {use}" for path, line, source in examples
                 for use in plugin_uses(source, loaders)]
    assert offenders == [], "doctests of multilayer/ that use a plugin (use a stand-in):\n" + "\n".join(offenders)


def test_the_doctest_check_catches_an_offender(tmp_path):
    """The check reads what it should: a module whose examples import a plugin and load the installed ones."""
    (tmp_path / "bad.py").write_text(textwrap.dedent('''\
        def f(registry=None):
            """The offenders.

            >>> from multilayer_plugins.planar import Planar
            >>> f()
            >>> f(registry=None), f(None)
            (None, None)
            """
        '''))
    loaders = registry_defaults(tmp_path)
    assert loaders == {"f": 0}
    found = [(line, use) for _, line, source in docstring_examples(tmp_path) for use in plugin_uses(source, loaders)]
    assert found == [(4, "imports multilayer_plugins"), (5, "f(...) without a registry: the installed plugins")]
