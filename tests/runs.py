"""Running a bundled case through the CLI, as a user would, and reading its results folder back."""

import csv
import json
from pathlib import Path

from multilayer.commands.main import main

CASES = Path(__file__).parents[1] / "cases"


def run_cli(case: str, out: Path, *sets: str) -> tuple[int, dict, list[dict[str, str]]]:
    """``multilayer run cases/<case>.toml --out OUT --set ...``: (exit code, summary.json, series.csv rows)."""
    argv = ["run", str(CASES / f"{case}.toml"), "--out", str(out), "--no-plots", "--quiet"]
    for s in sets:
        argv += ["--set", s]
    code = main(argv)
    summary = json.loads((Path(out) / "summary.json").read_text())
    with open(Path(out) / "series.csv") as fh:
        rows = list(csv.DictReader(fh))
    return code, summary, rows
