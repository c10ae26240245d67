"""The house's layering (pyproject.toml, ``[tool.importlinter]``) and the size of its modules, checked in CI."""

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
