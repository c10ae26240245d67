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
