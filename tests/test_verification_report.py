"""scripts/verification_report.py renders its tables from run folders (synthetic ones here: no case is run), and
docs/accuracy.md stays a page read in one sitting."""

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).parents[1]


@pytest.fixture(scope="module")
def vr():
    spec = importlib.util.spec_from_file_location("verification_report", ROOT / "scripts" / "verification_report.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["verification_report"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    yield module
    del sys.modules["verification_report"]


T = np.linspace(0.0, 1.0, 201)
PULSE = np.exp(-((T - 0.4) / 0.1) ** 2)  # a pulse that peaks at 1 at t = 0.4


def write_run(folder: Path, series: dict, *, dt=1e-3, wall=1.0, status="ok", tolerance=None, adaptive=None):
    """A results folder with what the report reads: summary.json and series.csv."""
    folder.mkdir(parents=True)
    summary = {"status": status, "case_hash": "x", "dt": dt, "steps": len(T) - 1, "wall_time_s": wall,
               "energy": {"max_relative_residual": 1.5e-13}, "volume": {"relative_drift": 2e-5},
               "case": {"time": {"dt": dt, **({"tolerance": tolerance} if tolerance else {})}}}
    if adaptive:
        summary["adaptive"] = adaptive
    (folder / "summary.json").write_text(json.dumps(summary))
    names = ["t", *series]
    rows = [",".join(names)] + [",".join(repr(float(v)) for v in row)
                                for row in zip(T, *series.values())]
    (folder / "series.csv").write_text("\n".join(rows) + "\n")


def test_peaks_and_errors_are_measured_against_the_reference(vr, tmp_path):
    study = vr.Study("tiny", "A tiny study", "cases/quick-start.toml", "peaks", probes=("eta_z1",), repeat=3,
                     reference=vr.Run("reference", text="reference"),
                     runs=(vr.Run("high", text="2 % high"), vr.Run("low", text="half")))
    write_run(tmp_path / "tiny" / "reference" / "0", {"eta_z1": 0.05 * PULSE}, dt=1e-4, wall=9.0)
    for i, wall in enumerate((3.0, 1.0, 2.0)):  # the median of the repeats is the wall time shown
        write_run(tmp_path / "tiny" / "high" / str(i), {"eta_z1": 0.051 * PULSE}, wall=wall)
        write_run(tmp_path / "tiny" / "low" / str(i), {"eta_z1": 0.025 * PULSE}, wall=10 * wall)
    lines = vr.peaks_table(study, tmp_path)
    assert lines[2] == "| reference | 0.0001 | 500.00 µm | 1.5e-13 | 9 |"
    assert lines[3] == "| 2 % high | 0.001 | +2.00 % | 1.5e-13 | 2 |"
    assert lines[4] == "| half | 0.001 | −50.00 % | 1.5e-13 | 20 |"

    errors = vr.Study("tiny", "A tiny study", "cases/quick-start.toml", "errors", probes=("eta_z1",), repeat=3,
                      reference=study.reference, runs=(vr.Run("high", ("time.tolerance=1e-2",), text="tol"),))
    # the tolerance is read from the run's own summary: 2 % against 1e-2 is 2.00
    write_run(tmp_path / "t2" / "tiny" / "reference" / "0", {"eta_z1": 0.05 * PULSE})
    for i in range(3):
        write_run(tmp_path / "t2" / "tiny" / "high" / str(i), {"eta_z1": 0.051 * PULSE}, wall=1.0 + i, tolerance=1e-2,
                  adaptive={"accepted": 120, "rejected": 3, "dt_range": [1e-5, 2e-3]})
    row = vr.errors_table(errors, tmp_path / "t2")[2]
    assert row == "| tol | ok | 120 (3) | 1e-05 … 0.002 | 2 | 2 % | 2 % | 2.00 | 1.5e-13 |"


def test_orders_and_the_cost_of_a_target_come_from_the_runs(vr, tmp_path):
    runs = tuple(vr.Run(f"{g}-{dt}", text="", group=g) for g in ("first", "second") for dt in ("a", "b", "c"))
    study = vr.Study("o", "Orders", "cases/quick-start.toml", "orders", probes=("eta_z1", "eta_z2"),
                     reference=vr.Run("reference"), runs=runs)
    write_run(tmp_path / "o" / "reference" / "0", {"eta_z1": PULSE, "eta_z2": 0.5 * PULSE})
    # "first" halves its error with Δt (order 1), "second" quarters it (order 2); the worst probe is eta_z2
    for g, errs in (("first", (0.08, 0.04, 0.02)), ("second", (0.08, 0.02, 0.005))):
        for dt, e, wall in zip((4e-4, 2e-4, 1e-4), errs, (1.0, 2.0, 4.0)):
            write_run(tmp_path / "o" / f"{g}-{'abc'[(4e-4, 2e-4, 1e-4).index(dt)]}" / "0",
                      {"eta_z1": PULSE * (1 + e / 2), "eta_z2": 0.5 * PULSE * (1 + e)}, dt=dt, wall=wall)
    text = "\n".join(vr.orders_tables(study, tmp_path))
    assert "| first | 0.0004 | 4.00 % | 8.00 % | 8 % | 1.5e-13 | 1 |" in text
    assert "| first | 1.00, 1.00 | 1.00, 1.00 |" in text
    assert "| second | 2.00, 2.00 | 2.00, 2.00 |" in text
    # 5 %: the cheapest run within it, both at Δt = 2e-4 (2 s); 1 %: "first" extrapolated from its finest run's 2 %
    # at order 1 (8 s), "second" measured (0.5 % in 4 s): 2× faster than the first coupler
    assert "| first | 2 | 8 (estimated, p = 1.00) | 1× |" in text
    assert "| second | 2 | 4 | 2× |" in text


def test_a_section_says_its_command_and_survives_a_partial_regeneration(vr, tmp_path):
    study = vr.STUDIES[0]
    section = vr.not_run(study)
    assert f"Not run yet: `{vr.command(study)}`." in section
    text = "intro\n" + "\n".join(section) + "\n"
    assert vr.sections_of(text) == {study.name: section}
    assert vr.anchor("Adaptive steps: the error a tolerance buys") == "adaptive-steps-the-error-a-tolerance-buys"
    names = [s.name for s in vr.STUDIES]
    assert len(set(names)) == len(names)
    for s in vr.STUDIES:  # every study can render: its table kind exists, timed studies have repeats
        assert s.table in vr.TABLES and s.repeat >= 1
        assert s.table == "scene" or s.reference is not None


def test_accuracy_is_a_page_read_in_one_sitting():
    assert len((ROOT / "docs" / "accuracy.md").read_text().splitlines()) <= 400


def test_a_report_keeps_what_it_does_not_regenerate(vr, tmp_path, monkeypatch):
    """--only and --render keep the sections of the studies whose runs the folder does not hold; a study never
    run says the command that runs it."""
    study = vr.Study("tiny", "A tiny study", "cases/quick-start.toml", "peaks", probes=("eta_z1",),
                     reference=vr.Run("reference", ("time.end=0.001",)), runs=(vr.Run("a", ("time.end=0.001",)),))
    monkeypatch.setattr(vr, "STUDIES", (study,))
    fresh = vr.report(tmp_path, set())
    assert f"Not run yet: `{vr.command(study)}`." in fresh and "- [A tiny study](#a-tiny-study)" in fresh
    earlier = fresh.replace("Not run yet", "A table made earlier; not run yet")
    assert "A table made earlier" in vr.report(tmp_path, set(), earlier)
