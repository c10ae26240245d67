"""The examples of docs/examples/ and the code of docs/python-api.md run, and give what they say they give.

Each example ends with one scalar; it is checked against the value measured
when the example was written.  The tolerances are far above round-off (a
run is reproducible to ~1e-12 relative; the Krylov tolerance is 1e-12) and
far below what any change of the discretization moves the scalar by: each
test's comment gives the change measured with a second setting, a mesh
refined from 30 × 4 to 60 × 8 cells and Δt halved from 1e-4 to 5e-5 s.
"""

from __future__ import annotations

import re
import runpy
import shutil
from pathlib import Path

import matplotlib
import pytest

ROOT = Path(__file__).parents[1]
EXAMPLES = ROOT / "docs" / "examples"
PAGE = ROOT / "docs" / "python-api.md"


@pytest.fixture
def run_example(tmp_path, monkeypatch):
    """Run ``docs/examples/<name>`` as a script in an empty folder; its globals."""
    monkeypatch.chdir(tmp_path)
    matplotlib.use("Agg")

    def run(name: str) -> dict:
        return runpy.run_path(str(EXAMPLES / name), run_name="__main__")

    return run


TESTED = {"ex01_energy_ledger.py", "ex02_wave_speed.py", "ex03_stop_at_threshold.py", "ex04_koiter_vs_wave.py",
          "ex05_results_folder.py"}


def test_every_example_is_tested():
    assert {p.name for p in EXAMPLES.glob("ex*.py")} == TESTED


def test_ex01_the_energy_ledger_closes_to_round_off(run_example):
    g = run_example("ex01_energy_ledger.py")
    # measured 4.1e-13 (30 x 4), 3.4e-13 (60 x 8), 4.8e-13 (Δt/2): round-off everywhere; a missing or wrong
    # energy term leaves a residual of the order of the term (the numerical dissipation is ~1e-2 of the work)
    assert g["max_relative_residual"] < 1e-9
    assert g["res"].ok and g["res"].steps == 40
    assert abs(g["budget"]) < 1e-9 * g["work"].sum()  # E(T) = W - D over the whole run


def test_ex02_the_pulse_speed(run_example):
    g = run_example("ex02_wave_speed.py")
    # 527.86 cm/s; the 60 x 8 mesh gives 525.30 (-0.48 %), Δt/2 534.02 (+1.2 %): 1e-4 catches either
    assert g["speed"] == pytest.approx(527.8570, rel=1e-4)


def test_ex03_stepping_stops_at_the_threshold(run_example):
    g = run_example("ex03_stop_at_threshold.py")
    # 3.86725 ms; the 60 x 8 mesh gives 3.85211 (-0.39 %), Δt/2 3.89520 (+0.72 %)
    assert g["crossing_ms"] == pytest.approx(3.867247, rel=1e-4)
    assert g["step"].n == 39  # the loop stopped there: no later step was computed


def test_ex04_koiter_shell_against_wave_membrane(run_example):
    g = run_example("ex04_koiter_vs_wave.py")
    # 0.62847; the 60 x 8 mesh gives 0.63756 (+1.4 %), Δt/2 0.58852 (-6.4 %)
    assert g["ratio"] == pytest.approx(0.628470, rel=1e-4)


def test_ex05_a_results_folder_read_back_and_plotted(run_example, tmp_path):
    g = run_example("ex05_results_folder.py")
    # 488.216 µm; the 60 x 8 mesh gives 490.946 (+0.56 %), Δt/2 501.844 (+2.8 %)
    assert g["peak_um"] == pytest.approx(488.2162, rel=1e-4)
    out = tmp_path / "results" / "ex05-pulse-koiter-thick"
    assert {"summary.json", "series.csv", "eta_lumen.csv", "eta.png"} <= {p.name for p in out.iterdir()}
    assert g["res"].ok and g["res"].folder == Path("results/ex05-pulse-koiter-thick")


def python_blocks(text: str) -> list[tuple[int, str]]:
    """(line of its first line of code, code) of every ```python block of a Markdown page."""
    return [(text.count("\n", 0, m.start()) + 2, m.group(1))
            for m in re.finditer(r"^```python\n(.*?)^```", text, re.DOTALL | re.MULTILINE)]


def test_python_blocks_are_found():
    assert python_blocks("x\n```python\na = 1\n```\n```text\nb\n```\n") == [(3, "a = 1\n")]


def test_the_python_api_page_runs(tmp_path, monkeypatch):
    """Every block of docs/python-api.md, in order in one session, from a folder with the bundled cases."""
    try:
        (tmp_path / "cases").symlink_to(ROOT / "cases", target_is_directory=True)
    except OSError:  # no symlinks here
        shutil.copytree(ROOT / "cases", tmp_path / "cases")
    monkeypatch.chdir(tmp_path)
    matplotlib.use("Agg")
    blocks = python_blocks(PAGE.read_text())
    assert len(blocks) >= 10
    session: dict = {"__name__": "__main__"}
    for line, code in blocks:
        # blank lines first: a traceback names the page's own line
        exec(compile("\n" * (line - 1) + code, str(PAGE), "exec"), session)  # noqa: S102
    # what the page says its blocks show
    assert session["res"].ok and session["saved"].ok and session["back"].ok
    assert session["failed"].status == session["crashed"].status == "failed"
    assert session["same"].digest == session["accurate"].digest
    assert all(r.ok for r in session["runs"].values())
    assert (tmp_path / "results" / "quick" / "eta.png").is_file()
    assert (tmp_path / "results" / "koiter-vs-wave.png").is_file()
