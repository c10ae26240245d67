"""Running a bundled case through the CLI, as a user would, and reading its results folder back."""

import csv
import json
from pathlib import Path

from multilayer.case.casefile import load_case
from multilayer.commands.main import main
from multilayer.results.reading import read_run
from multilayer.runner.loop import run_case

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



def run_case_file(case: str, out: Path, *sets: str, registry=None):
    """``cases/<case>.toml`` with ``--set`` overrides run through the library: (RunResult, RunData read back)."""
    result = run_case(load_case(CASES / f"{case}.toml", sets, registry), out, registry)
    return result, read_run(Path(out).name, Path(out))


def assert_resume_is_bit_identical(tmp_path: Path, case: str, *sets: str, every: int = 10,
                                   half: float = 0.002, end: float = 0.004) -> None:
    """A run to ``end`` with checkpoints, and one to ``half`` resumed to ``end``, write the same bytes."""
    def argv(out, t):
        return ["run", str(CASES / f"{case}.toml"), "--out", str(out), "--quiet", "--no-plots",
                "--checkpoint-every", str(every), *(a for s in (*sets, f"time.end={t}") for a in ("--set", s))]

    full, cut = tmp_path / "full", tmp_path / "half"
    assert main(argv(full, end)) == 0
    assert main(argv(cut, half)) == 0
    assert main(["resume", str(cut), "--until", str(end), "--quiet", "--no-plots"]) == 0
    for name in ("series.csv", "eta_lumen.csv", "wss_lumen.csv"):
        assert (full / name).read_bytes() == (cut / name).read_bytes(), name
