"""The verification report, docs/verification.md: every study's runs made (or found) and its tables rendered from them.

    python scripts/verification_report.py [--out studies/verification] [--doc docs/verification.md] \
        [--only STUDY[,STUDY...]] [--render] [--fresh] [--list]

A study (:data:`STUDIES`) is a case, the ``--set`` overrides all its runs
share, a reference run, its runs (each with overrides of its own) and the
probes measured; its tables are made from the runs' ``summary.json`` and
``series.csv`` (:mod:`multilayer.campaign.run_tables`), never typed.

Runs go into ``OUT/STUDY/LABEL/I`` (I the repeat).  A run already there,
finished, of the same resolved case (``summary.json``: its ``case_hash``)
is not run again, so an interrupted regeneration resumes and ``--only``
regenerates one study; ``--fresh`` runs them again anyway (new code, same
inputs).  The timed runs of a study are repeated ``repeat`` times taking
turns (run 1, run 2, …, then again), so a shared machine's load falls on
all of them alike, and the tables give the median wall time.

Each study's section of the report says the command that made it, the
commit and the date of its runs; a study not run yet says the command that
runs it.  ``--only`` and ``--render`` keep the sections of the other
studies as the report has them unless OUT holds all their runs;
``--render`` runs nothing.  ``--list`` prints the studies and their runs.
"""

from __future__ import annotations

import argparse
import datetime
import json
import re
import statistics
import subprocess
import sys
import textwrap
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from multilayer.campaign.accuracy import cost_cell, cost_to_target, observed_orders
from multilayer.campaign.run_tables import (
    centreline_changes,
    dt_cell,
    errors_against,
    markdown,
    peak_changes,
    peaks,
    percent,
    scene_cells,
    scene_header,
    signed_percent,
    steps_taken,
)
from multilayer.case.casefile import load_case
from multilayer.results.reading import RunData, read_run

ROOT = Path(__file__).resolve().parents[1]
COMMAND = "python scripts/verification_report.py"


@dataclass(frozen=True)
class Run:
    """One run of a study: its label (its folder), its own overrides, and what it is in the table."""

    label: str
    sets: tuple[str, ...] = ()
    text: str = ""  #: the row's name (the label when empty)
    group: str = ""  #: the coupler a Δt sequence belongs to (tables of orders)


@dataclass(frozen=True)
class Study:
    """A case, the overrides every run takes, a reference, the runs and how their table is made."""

    name: str
    title: str
    case: str
    table: str  #: "peaks", "errors", "orders" or "scene"
    runs: tuple[Run, ...]
    sets: tuple[str, ...] = ()
    reference: Run | None = None
    probes: tuple[str, ...] = ()
    repeat: int = 1  #: times each run (not the reference) is run, taking turns: its wall time is the median
    after: float = 0.0  #: errors over t ≥ after (a periodic run's last cycle)
    about: str = ""  #: what the study measures and how to read its table (no numbers: those are the table's)
    options: dict = field(default_factory=dict)  #: the table's own settings

    def all_runs(self) -> list[tuple[Run, int]]:
        """(run, repeat) pairs in the order they are run: the reference first, then the runs taking turns."""
        first = [(self.reference, 0)] if self.reference else []
        return first + [(run, i) for i in range(self.repeat) for run in self.runs]


def coupler(spec: str) -> str:
    return f"coupler={spec}"


#: the couplers of the studies in Δt, the paper's first (the baseline of "× faster"): (label, TOML value, group)
COUPLERS = (
    ("paper-be", '{model="kinematic-splitting",robin="inertia"}', "the paper's splitting (BE)"),
    ("paper-be-beta1", '{model="kinematic-splitting",robin="inertia",beta=1}', "the paper's splitting, β = 1 (BE)"),
    ("paper-cn-beta1", '{model="kinematic-splitting",robin="inertia",scheme="crank-nicolson",beta=1}',
     "the paper's splitting, CN, β = 1"),
    ("splitting-be", '"kinematic-splitting"', "splitting under the impedance, BE (the default)"),
    ("splitting-cn", '{model="kinematic-splitting",scheme="crank-nicolson"}', "splitting under the impedance, CN"),
    ("monolithic-be", '{model="monolithic"}', "monolithic BE"),
    ("monolithic-cn", '{model="monolithic",scheme="crank-nicolson"}', "monolithic CN"),
    ("monolithic-bdf2", '{model="monolithic",scheme="bdf2"}', "monolithic BDF2"),
    ("monolithic-tr-bdf2", '{model="monolithic",scheme="tr-bdf2"}', "monolithic TR-BDF2"),
)
MONOLITHIC_CN = coupler('{model="monolithic",scheme="crank-nicolson"}')


def dt_sweep(dts: Sequence[str]) -> tuple[Run, ...]:
    return tuple(Run(f"{label}-{dt}", (coupler(spec), f"time.dt={dt}"), text=f"{group}, Δt = {dt}", group=group)
                 for label, spec, group in COUPLERS for dt in dts)


def tolerance_runs(prefix: str, spec: str, text: str, tolerances: Sequence[str], extra: Sequence[str] = ()) -> tuple[Run, ...]:
    return tuple(Run(f"{prefix}-tol{tol}", (coupler(spec), f"time.tolerance={tol}", *extra), text=f"{text}, tol {tol}",
                     group=text) for tol in tolerances)


#: the light wall of tests/test_adaptive.py's stability test: ρ₁h/(ρ_f R) = 1e-3 on a short coarse channel
LIGHT_WALL = ('layers[0]={ model = "koiter-shell", density = 1.0, thickness = 0.0005, young = 7.5e7, poisson = 0.49 }',
              "geometry.length=2.0", "mesh.nz=8", "mesh.nr=2", "time.end=0.02", "solver.volume_margin=2",
              'output.probes=[{ name = "eta_z1", quantity = "eta", z = 1.0 }]')
CAROTID_PROBES = ("eta_z1", "eta_z3", "eta_z5", "eta_z55", "p_out")
TR_BDF2 = '{model="monolithic",scheme="tr-bdf2"}'
#: SUPG's Δt_τ of the studies of adaptive steps on an artery: τ_M as at a step below every run's, the reference's too
SUPG_DT = "2.5e-5"

STUDIES: tuple[Study, ...] = (
    Study(
        "quick-start", "The quick start's answer, by coupler", "cases/quick-start.toml", "peaks",
        probes=("eta_z1", "eta_z2", "eta_z3", "eta_z4"), repeat=3,
        reference=Run("reference", ("time.dt=1.25e-5",), text="reference: the case at Δt = 1.25e-5"),
        sets=("solver.volume_margin=2",),
        runs=(
            Run("monolithic-cn", (), text="**the case as bundled: monolithic CN**"),
            Run("splitting-cn", (coupler('{model="kinematic-splitting",scheme="crank-nicolson"}'),),
                text="splitting under the impedance, CN"),
            Run("splitting-be", (coupler('"kinematic-splitting"'),), text="splitting under the impedance, BE"),
            Run("monolithic-tr-bdf2", (coupler(TR_BDF2),), text="monolithic TR-BDF2"),
            Run("paper-cn-beta1", (coupler(COUPLERS[2][1]),), text="the paper's splitting, CN, β = 1"),
            Run("paper-cn-beta1-5e-5", (coupler(COUPLERS[2][1]), "time.dt=5e-5"),
                text="the paper's splitting, CN, β = 1, Δt = 5e-5"),
            Run("paper-be", (coupler(COUPLERS[0][1]),), text="the paper's splitting (BE)"),
        ),
        about="`cases/quick-start.toml` (the composite wall's pulse, 60 × 8 cells, to T = 30 ms at Δt = 1e-4) "
              "by each coupler at the case's Δt: the relative difference of the peak η at z = 1 … 4 cm from a "
              "reference 8× finer in Δt, the energy ledger's largest relative residual, the median wall time. "
              "Every run takes `solver.volume_margin=2`: the paper's Robin term loses volume through the wall."),
    Study(
        "couplers-composite", "Every coupler in the time step: the composite wall",
        "cases/pulse-koiter-thick.toml", "orders", probes=("eta_z1", "eta_z2", "eta_z3"), repeat=3,
        sets=("solver.volume_margin=2", "solver.energy_margin=0.05"),
        reference=Run("reference", (MONOLITHIC_CN, "time.dt=3.125e-6"), text="monolithic CN, Δt = 3.125e-6"),
        runs=dt_sweep(("1e-4", "5e-5", "2.5e-5")),
        about="`cases/pulse-koiter-thick.toml` (a Koiter shell on a thick band, 60 × 8 cells, P2/P1, T = 12 ms) "
              "by every coupler at Δt = 1e-4, 5e-5, 2.5e-5, against monolithic Crank–Nicolson 8× finer than "
              "the finest. Errors at z = 1, 2, 3 cm, where the pulse has passed within T: the peak error per "
              "probe and the relative L∞ error of η(t) (which also counts a shift in time), the worst over the "
              "probes; the cost is the run's median wall time. The orders are between successive Δt; the cost of "
              "a target error is the cheapest run that reaches it, else extrapolated from the finest run with the "
              "last observed order (\"estimated\")."),
    Study(
        "couplers-koiter", "Every coupler in the time step: the Koiter shell alone",
        "cases/pulse-koiter.toml", "orders", probes=("eta_z1", "eta_z2", "eta_z3"),
        sets=("solver.volume_margin=2", "solver.energy_margin=0.05"),
        reference=Run("reference", (MONOLITHIC_CN, "time.dt=3.125e-6"), text="monolithic CN, Δt = 3.125e-6"),
        runs=dt_sweep(("1e-4", "5e-5", "2.5e-5")),
        about="The same on `cases/pulse-koiter.toml`: a Koiter shell (h = 0.1 cm) alone, a heavier wall "
              "against the fluid than the composite one's shell (ρ₁h/(ρ_f R) = 0.22); columns as above, each "
              "run once (its wall time is one run's)."),
    Study(
        "couplers-membrane", "Every coupler in the time step: the wave membrane alone",
        "cases/pulse-membrane.toml", "orders", probes=("eta_z1", "eta_z2", "eta_z3"),
        sets=("solver.volume_margin=2", "solver.energy_margin=0.05"),
        reference=Run("reference", (MONOLITHIC_CN, "time.dt=3.125e-6"), text="monolithic CN, Δt = 3.125e-6"),
        runs=dt_sweep(("1e-4", "5e-5", "2.5e-5")),
        about="The same on `cases/pulse-membrane.toml`: a wave membrane (tension only, no hoop stiffness) "
              "alone instead of the Koiter shell; columns as above, each run once."),
    Study(
        "light-wall", "The lightest wall: every coupler at a mass ratio of 1e-3", "cases/pulse-koiter.toml", "errors",
        probes=("eta_z1",), sets=LIGHT_WALL,
        reference=Run("reference", (MONOLITHIC_CN, "time.dt=2.5e-6"), text="monolithic CN, Δt = 2.5e-6"),
        runs=tuple(Run(f"{label}-1e-4", (coupler(spec), "time.dt=1e-4"), text=f"{group}, Δt = 1e-4")
                   for label, spec, group in (COUPLERS[0], COUPLERS[2], COUPLERS[3], COUPLERS[4], COUPLERS[5],
                                              COUPLERS[6], COUPLERS[8]))
        + (Run("paper-cn-beta1-2.5e-5", (coupler(COUPLERS[2][1]), "time.dt=2.5e-5"),
               text=f"{COUPLERS[2][2]}, Δt = 2.5e-5"),
           Run("monolithic-cn-tol1e-3", (MONOLITHIC_CN, "time.dt=1e-6", "time.tolerance=1e-3", "time.dt_max=1e-4"),
               text="monolithic CN, tol 1e-3"),
           Run("paper-cn-beta1-tol1e-2", (coupler(COUPLERS[2][1]), "time.dt=1e-6", "time.tolerance=1e-2",
                                          "time.dt_max=1e-4"), text=f"{COUPLERS[2][2]}, tol 1e-2")),
        about="The light-wall scene of the stability tests: `cases/pulse-koiter.toml` with a Koiter shell of "
              "ρ₁ = 1, h = 5e-4 cm (ρ₁h/(ρ_f R) = 1e-3, 220× lighter against the fluid than the bundled shell), "
              "a 2 cm channel on 8 × 2 cells, to 20 ms: each coupler's error at z = 1 cm against monolithic "
              "Crank–Nicolson at Δt = 2.5e-6, and two adaptive runs (`time.dt_max` = 1e-4)."),
    Study(
        "calibration", "Adaptive steps: the error a tolerance buys", "cases/pulse-koiter-thick.toml", "errors",
        probes=("eta_z1", "eta_z2", "eta_z3"),
        sets=("mesh.nz=24", "mesh.nr=4", "time.dt=1e-6", "solver.volume_margin=2", "solver.energy_margin=0.05"),
        reference=Run("reference", (MONOLITHIC_CN, "time.dt=2.5e-6"), text="monolithic CN, Δt = 2.5e-6"),
        runs=(tolerance_runs("monolithic-cn", '{model="monolithic",scheme="crank-nicolson"}', "monolithic CN",
                             ("1e-2", "1e-3", "1e-4"))
              + tolerance_runs("monolithic-bdf2", '{model="monolithic",scheme="bdf2"}', "monolithic BDF2",
                               ("1e-2", "1e-3", "1e-4"))
              + tolerance_runs("monolithic-tr-bdf2", TR_BDF2, "monolithic TR-BDF2", ("1e-2", "1e-3", "1e-4"))
              + tolerance_runs("splitting-tr-bdf2", '{model="kinematic-splitting",scheme="tr-bdf2"}',
                               "splitting under the impedance, TR-BDF2", ("1e-2", "1e-3", "1e-4"))
              + tolerance_runs("paper-cn-beta1", COUPLERS[2][1], "the paper's splitting, CN, β = 1",
                               ("1e-2", "1e-3", "1e-4"))
              + tolerance_runs("monolithic-cn-per-unit-step", '{model="monolithic",scheme="crank-nicolson"}',
                               "monolithic CN per unit step", ("1e-2", "1e-3", "1e-4"),
                               ('time.control="per-unit-step"',))
              + tuple(Run(f"monolithic-cn-fixed-{dt}", (MONOLITHIC_CN, f"time.dt={dt}"),
                          text=f"monolithic CN, fixed Δt = {dt}") for dt in ("2e-4", "1e-4", "5e-5", "2.5e-5"))),
        about="The composite wall's pulse on 24 × 4 cells (the time error alone: the reference is on the same "
              "mesh), first step 1e-6 s, each adaptive coupler at tolerances 1e-2, 1e-3, 1e-4 (per-step "
              "control, the default). The error is the largest over η at z = 1, 2, 3 cm of the relative L∞ "
              "error; error / tolerance is the calibration (1 is exact). The last runs share the tolerance per unit step "
              "(`time.control = \"per-unit-step\"`) instead, and the last ones are fixed steps, for comparison. "
              "BDF2 runs need "
              "`solver.energy_margin=0.05` (its G-norm depends on the step ratio, theory §4)."),
    Study(
        "carotid", "The carotid-like artery: its checks, and refined in space", "cases/carotid.toml", "scene",
        runs=(Run("carotid", (), text="the case as bundled (30 × 4, Δt = 1e-3, 3 cycles)"),
              Run("carotid-60x8", ("time.end=1.0", "mesh.nz=60", "mesh.nr=8", "time.dt=5e-4"),
                  text="60 × 8, Δt = 5e-4, one cycle"),
              Run("f30", ("time.end=0.5", "time.dt=2.5e-4"), text="30 × 4, Δt = 2.5e-4, to 0.5 s"),
              Run("f60", ("time.end=0.5", "time.dt=2.5e-4", "mesh.nz=60", "mesh.nr=8"),
                  text="60 × 8, Δt = 2.5e-4, to 0.5 s"),
              Run("m120", ("time.end=0.5", "time.dt=2.5e-4", "mesh.nz=120", "mesh.nr=16"),
                  text="120 × 16, Δt = 2.5e-4, to 0.5 s")),
        options={"radius": 0.3, "refinements": (("carotid", "carotid-60x8"), ("f30", "f60"), ("f60", "m120"))},
        about="`cases/carotid.toml` as bundled and refined. Read the columns as checks: energy, the ledger's "
              "largest relative residual (theory §7); volume drift, the lumen's volume against the flow through "
              "its ends over the volume moved; `p_out` over the last cycle in mmHg and its change from the cycle "
              "before (periodic); the centreline velocity at z = 3 and 5.5 cm over the section's mean velocity "
              "Q/(π(R + η)²), where that mean exceeds 5 cm/s (a profile stays a profile between 0 and 2.5). The "
              "second table: the largest change of the centreline velocity from one mesh to the next."),
    Study(
        "carotid-couplers", "The carotid-like artery's first systole, by coupler", "cases/carotid.toml", "scene",
        sets=("time.end=0.25",),
        runs=tuple(Run(f"{label}-{nz}x{nr}", (coupler(spec), f"mesh.nz={nz}", f"mesh.nr={nr}"),
                       text=f"{group}, {nz} × {nr}")
                   for nz, nr in ((20, 3), (60, 8))
                   for label, spec, group in (COUPLERS[3], COUPLERS[4], COUPLERS[5], COUPLERS[6], COUPLERS[7],
                                              COUPLERS[8],
                                              ("dn-implicit", '{model="dirichlet-neumann-implicit"}',
                                               "Dirichlet–Neumann, implicit")))
        + tuple(Run(f"{label}-2.5e-4", (coupler(spec), "mesh.nz=20", "mesh.nr=3", "time.dt=2.5e-4"),
                    text=f"{group}, 20 × 3, Δt = 2.5e-4")
                for label, spec, group in (COUPLERS[4], COUPLERS[6], COUPLERS[7])),
        options={"radius": 0.3},
        about="Every coupler that takes a flow-rate inlet (`dirichlet-neumann-explicit` and the paper's Robin "
              "term refuse this case up front, saying why) through the first systole, t = 0.25 s, on 20 × 3 and "
              "60 × 8 cells at the case's Δt = 1e-3, and the Crank–Nicolson ones at Δt = 2.5e-4; columns as in "
              "the carotid's checks."),
    Study(
        "carotid-steps", "The carotid-like artery, three cycles: adaptive steps against fixed ones",
        "cases/carotid.toml", "errors", probes=CAROTID_PROBES, repeat=3, after=2.0, sets=(f"fluid.supg_dt={SUPG_DT}",),
        reference=Run("reference", (coupler(TR_BDF2), "time.dt=1.25e-4"), text="monolithic TR-BDF2, Δt = 1.25e-4"),
        runs=(Run("splitting-be-1e-3", ("time.dt=1e-3",), text="the case's coupler (splitting, BE), Δt = 1e-3"),
              Run("monolithic-bdf2-1e-3", (coupler('{model="monolithic",scheme="bdf2"}'), "time.dt=1e-3"),
                  text="monolithic BDF2, Δt = 1e-3"),
              *(Run(f"monolithic-tr-bdf2-{dt}", (coupler(TR_BDF2), f"time.dt={dt}"), text=f"monolithic TR-BDF2, Δt = {dt}")
                for dt in ("4e-3", "2e-3", "1e-3")),
              *(Run(f"tr-bdf2-tol{tol}", (coupler(TR_BDF2), "time.dt=1e-3", f"time.tolerance={tol}", "time.size=memory"),
                    text=f"TR-BDF2, tol {tol}, `size = \"memory\"`") for tol in ("2e-4", "1e-4", "5e-5")),
              Run("tr-bdf2-1e-3-own-tau", (coupler(TR_BDF2), "time.dt=1e-3", "fluid.supg_dt=1e9"),
                  text="monolithic TR-BDF2, Δt = 1e-3, τ_M its step's own (fixed steps' default)"),
              Run("tr-bdf2-1e-3-least-tau", (coupler(TR_BDF2), "time.dt=1e-3", "fluid.supg_dt=1e-9"),
                  text="monolithic TR-BDF2, Δt = 1e-3, τ_M at Δt_τ = 1e-9 (an adaptive run's default)")),
        about="`cases/carotid.toml` (30 × 4 cells, three cycles of 1 s), the errors over the third cycle (the "
              "periodic answer): the largest over η at z = 1, 3, 5, 5.5 cm and the outlet pressure `p_out` of the "
              "relative L∞ error and of the peak error, against monolithic TR-BDF2 at Δt = 1.25e-4. Every run, "
              f"the reference too, takes `fluid.supg_dt = {SUPG_DT}`, so all solve one stabilized problem and the "
              "errors are the time schemes' (the last two rows show what SUPG's share is: the step's own τ_M, "
              "and τ_M at a vanishing Δt_τ). Adaptive runs start at `time.dt = 1e-3`. Each run three times, "
              "taking turns: the median wall time."),
    Study(
        "aortic-flow", "Aortic inflow, three cycles: adaptive steps against fixed ones",
        "cases/physiological-flow.toml", "errors", probes=("eta_z1", "eta_z2", "eta_z3", "eta_z4", "eta_z5"),
        sets=("mesh.nz=15", "mesh.nr=3", f"fluid.supg_dt={SUPG_DT}"),
        reference=Run("reference", ("time.dt=1.25e-4",), text="monolithic CN, Δt = 1.25e-4"),
        runs=(Run("fixed-4e-3", ("time.dt=4e-3",), text="monolithic CN, Δt = 4e-3"),
              Run("fixed-2e-3", ("time.dt=2e-3",), text="monolithic CN, Δt = 2e-3"),
              Run("fixed-1e-3", ("time.dt=1e-3",), text="monolithic CN, Δt = 1e-3"),
              Run("tol1e-2", ("time.dt=1e-4", "time.tolerance=1e-2", "time.dt_min=1e-6"), text="monolithic CN, tol 1e-2"),
              Run("tol1e-2-max8e-3", ("time.dt=1e-4", "time.tolerance=1e-2", "time.dt_max=8e-3", "time.dt_min=1e-6"),
                  text="monolithic CN, tol 1e-2, `dt_max` 8e-3"),
              Run("tol3e-3-max8e-3", ("time.dt=1e-4", "time.tolerance=3e-3", "time.dt_max=8e-3", "time.dt_min=1e-6"),
                  text="monolithic CN, tol 3e-3, `dt_max` 8e-3"),
              Run("tol1e-3-max8e-3", ("time.dt=1e-4", "time.tolerance=1e-3", "time.dt_max=8e-3", "time.dt_min=1e-6"),
                  text="monolithic CN, tol 1e-3, `dt_max` 8e-3")),
        about="`cases/physiological-flow.toml` (an aortic-like inflow of one beat a second into the wall and "
              "Windkessel of `physiological-rcr`, from diastolic equilibrium; the waveform with the longest quiet "
              "phase here) on 15 × 3 cells, three cycles, monolithic Crank–Nicolson, fixed against adaptive "
              "steps (per-step control, each field's size over the last cycle), against Δt = 1.25e-4; every run "
              f"takes `fluid.supg_dt = {SUPG_DT}` (one stabilized problem)."),
)


# -- running -----------------------------------------------------------------------


def folder_of(out: Path, study: Study, run: Run, i: int) -> Path:
    return out / study.name / run.label / str(i)


def overrides(study: Study, run: Run) -> list[str]:
    return [*study.sets, *run.sets]


def finished(folder: Path, digest: str) -> bool:
    """Whether ``folder`` holds a run of the case with ``digest`` that ended (ok or failed: either is a result)."""
    try:
        summary = json.loads((folder / "summary.json").read_text())
    except (OSError, ValueError):
        return False
    return summary.get("case_hash") == digest and summary.get("status") in ("ok", "failed")


def commit() -> str:
    """The checkout's commit, "+ changes" when the code or the cases a run reads differ from it."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short=10", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                              check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", "multilayer",
                                "multilayer_plugins", "cases"], cwd=ROOT, capture_output=True,
                               text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + (" + changes" if dirty else "")


def record_path(out: Path, study: Study) -> Path:
    return out / study.name / "record.json"


def run_study(study: Study, out: Path, fresh: bool = False, say: Callable[[str], None] = print) -> None:
    """Make the study's runs that ``out`` does not hold yet (all of them with ``fresh``), taking turns."""
    from multilayer.runner.loop import run_case

    path = record_path(out, study)
    record = json.loads(path.read_text()) if path.is_file() else {"runs": {}}
    start = time.perf_counter()
    here, made = commit(), 0
    todo = study.all_runs()
    for k, (run, i) in enumerate(todo, 1):
        case = load_case(ROOT / study.case, overrides(study, run))
        folder = folder_of(out, study, run, i)
        key = f"{run.label}/{i}"
        if not fresh and finished(folder, case.digest):
            say(f"[{study.name}] {k}/{len(todo)} {key}: there already")
            continue
        result = run_case(case, folder, force=True)
        summary = json.loads((folder / "summary.json").read_text())
        record["runs"][key] = {"commit": here, "date": datetime.date.today().isoformat()}
        made += 1
        say(f"[{study.name}] {k}/{len(todo)} {key}: {result.status}, {summary['wall_time_s']:.3g} s")
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(record, indent=1))
    elapsed = time.perf_counter() - start
    if made:
        record["wall_time_s"] = elapsed
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record, indent=1))
    say(f"[{study.name}] {made} runs made, {len(todo) - made} there already: {elapsed:.0f} s")


def complete(study: Study, out: Path) -> bool:
    """Whether ``out`` holds every run of the study (as its case is now)."""
    return all(finished(folder_of(out, study, run, i), load_case(ROOT / study.case, overrides(study, run)).digest)
               for run, i in study.all_runs())


# -- the tables ------------------------------------------------------------------------


def read(out: Path, study: Study, run: Run, i: int = 0) -> RunData:
    return read_run(run.label, folder_of(out, study, run, i))


def wall_times(out: Path, study: Study, run: Run) -> list[float]:
    return [read(out, study, run, i).summary["wall_time_s"] for i in range(study.repeat)]


def median_wall(out: Path, study: Study, run: Run) -> float:
    return statistics.median(wall_times(out, study, run))


def ledger(run: RunData) -> str:
    return f"{run.summary['energy']['max_relative_residual']:.1e}"


def name(run: Run) -> str:
    return run.text or run.label


def peaks_table(study: Study, out: Path) -> list[str]:
    ref = read(out, study, study.reference)
    header = ["run", "Δt (s)", *(f"peak {p}" for p in study.probes), "ledger", "median wall time (s)"]
    rows = [[name(study.reference), f"{ref.summary['dt']:g}",
             *(f"{1e4 * v:.2f} µm" if p.startswith("eta") else f"{v:.6g}" for p, v in zip(study.probes,
                                                                                    peaks(ref, study.probes))),
             ledger(ref), f"{ref.summary['wall_time_s']:.3g}"]]
    for run in study.runs:
        data = read(out, study, run)
        if data.summary["status"] != "ok":
            rows.append([name(run), f"{data.summary['dt']:g}", *(["—"] * len(study.probes)), data.summary["status"],
                         f"{median_wall(out, study, run):.3g}"])
            continue
        rows.append([name(run), f"{data.summary['dt']:g}",
                     *(signed_percent(c) for c in peak_changes(data, ref, study.probes)), ledger(data),
                     f"{median_wall(out, study, run):.3g}"])
    return markdown(header, rows)


def errors_table(study: Study, out: Path) -> list[str]:
    ref = read(out, study, study.reference)
    tolerant = any(any(s.startswith("time.tolerance=") for s in run.sets) for run in study.runs)
    header = ["run", "status", "steps (rejected)", "Δt (s)", "median wall time (s)", "L∞ error", "peak error",
              *(["error / tolerance"] if tolerant else []), "ledger"]
    rows = []
    for run in study.runs:
        data = read(out, study, run)
        accepted, rejected, (small, large) = steps_taken(data.summary)
        linf, peak = (errors_against(data, ref, study.probes, study.after) if data.summary["status"] == "ok"
                      else (float("nan"),) * 2)
        tol = (data.summary.get("case", {}).get("time") or {}).get("tolerance")
        ratio = [f"{linf / tol:.2f}" if tol and np.isfinite(linf) else "—"] if tolerant else []
        rows.append([name(run), data.summary["status"], f"{accepted} ({rejected})", dt_cell(small, large),
                     f"{median_wall(out, study, run):.3g}", percent(linf), percent(peak), *ratio, ledger(data)])
    return markdown(header, rows)


TARGETS = (0.05, 0.01)


def orders_tables(study: Study, out: Path) -> list[str]:
    ref = read(out, study, study.reference)
    groups: dict[str, list[tuple[float, float, float, float, list[float]]]] = {}
    rows = []
    for run in study.runs:
        data = read(out, study, run)
        dt = data.summary["dt"]
        if data.summary["status"] != "ok":
            rows.append([run.group, f"{dt:g}", *(["—"] * len(study.probes)), "—", data.summary["status"], "—"])
            continue
        per_probe = [errors_against(data, ref, [p]) for p in study.probes]
        linf = max(e[0] for e in per_probe)
        peak = max(e[1] for e in per_probe)
        wall = median_wall(out, study, run)
        groups.setdefault(run.group, []).append((dt, peak, linf, wall, [e[1] for e in per_probe]))
        rows.append([run.group, f"{dt:g}", *(f"{100 * e[1]:.2f} %" for e in per_probe), percent(linf), ledger(data),
                     f"{wall:.3g}"])
    lines = markdown(["coupler", "Δt (s)", *(f"peak error {p}" for p in study.probes), "L∞ error", "ledger",
                      "median wall time (s)"], rows)
    orders, order_rows = {}, []
    for group, found in groups.items():
        found.sort(key=lambda r: -r[0])
        p = observed_orders([r[0] for r in found], [r[1] for r in found])
        q = observed_orders([r[0] for r in found], [r[2] for r in found])
        orders[group] = (found, p)
        order_rows.append([group, ", ".join("—" if x is None else f"{x:.2f}" for x in p),
                           ", ".join("—" if x is None else f"{x:.2f}" for x in q)])
    lines += ["", *markdown(["coupler", "orders of the worst peak error", "orders of the worst L∞ error"], order_rows)]
    costs = {group: [cost_to_target([r[3] for r in found], [r[1] for r in found], target, finest=len(found) - 1,
                                    order=p[-1] if p else None) for target in TARGETS]
             for group, (found, p) in orders.items()}
    base = next(iter(costs.values()), None)
    cost_rows = []
    for group, got in costs.items():
        cells = [cost_cell(g) for g in got]
        ratio = (f"{base[1]['wall_time_s'] / got[1]['wall_time_s']:.3g}×"
                 if base and base[1]["wall_time_s"] and got[1]["wall_time_s"] else "—")
        cost_rows.append([group, *cells, ratio])
    first = next(iter(costs), "—")
    lines += ["", *markdown(["coupler", "wall time to 5 % peak error (s)", "to 1 % (s)",
                             f"1 %: faster than {first}"], cost_rows)]
    return lines


def scene_tables(study: Study, out: Path) -> list[str]:
    pairs = [tuple(x.split(":")) for x in study.options.get("centreline", "u_axis_z3:q_mid:eta_z3,"
                                                                             "u_axis_z55:q_out:eta_z55").split(",")]
    radius = study.options["radius"]
    runs = {run.label: read(out, study, run) for run in study.runs}
    rows = [[name(run), *scene_cells(runs[run.label], radius, pairs)] for run in study.runs]
    lines = markdown(["run", *scene_header(pairs)], rows)
    refinements = study.options.get("refinements", ())
    if refinements:
        change_rows = []
        for a, b in refinements:
            t0 = runs[a].t[runs[a].t <= min(runs[a].t[-1], runs[b].t[-1])]
            change_rows.append([f"{a} → {b}", *(f"{c:.2f}" for c in centreline_changes(runs[a], runs[b],
                                                                                       [p for p, _, _ in pairs], t0))])
        lines += ["", *markdown(["runs", *(f"max change of {p} (cm/s)" for p, _, _ in pairs)], change_rows)]
    return lines


TABLES = {"peaks": peaks_table, "errors": errors_table, "orders": orders_tables, "scene": scene_tables}


# -- the report ------------------------------------------------------------------------

HEADER = """# Verification report

The measurements behind [accuracy](accuracy.md): each study below is a set
of runs of a bundled case, and its tables are made by
`scripts/verification_report.py` from those runs' `summary.json` and
`series.csv` — nothing in them is typed. One command regenerates the whole
report (runs already in its folder, of the same case, are not run again):

    python scripts/verification_report.py --out studies/verification

and `--only STUDY` one study. Errors are relative: the L∞ error is
max_t |y − y_ref| / max_t |y_ref| (the reference interpolated onto the
run's times), the peak error |max y − max y_ref| / max y_ref, each the
largest over the study's probes; "ledger" is the energy ledger's largest
relative residual over the steps ([theory](theory.md) §7). Wall times are
medians over the repeats a study says, its runs taking turns on a 2-core
machine shared with other work: read their ratios, not the seconds.
"""


def begin(study: Study) -> str:
    return f"<!-- study: {study.name} -->"


def end(study: Study) -> str:
    return f"<!-- end of study: {study.name} -->"


def command(study: Study) -> str:
    return f"{COMMAND} --out studies/verification --only {study.name}"


def described(study: Study) -> list[str]:
    sets = " ".join(f"`--set {s}`" for s in study.sets)
    made = f"`{study.case}`" + (f" with {sets}" if sets else "")
    runs = f"{len(study.runs)} runs" + (f" × {study.repeat}" if study.repeat > 1 else "")
    ref = f", against {name(study.reference)}" if study.reference else ""
    return [f"## {study.title}", "", textwrap.fill(study.about, 100), "",
            textwrap.fill(f"Runs: {made}; {runs}{ref}.", 100, break_on_hyphens=False)]


def rendered(study: Study, out: Path) -> list[str]:
    """The study's section from its runs in ``out``."""
    record = json.loads(record_path(out, study).read_text()) if record_path(out, study).is_file() else {"runs": {}}
    made = sorted({(r["commit"], r["date"]) for r in record["runs"].values()})
    when = "; ".join(f"commit {c}, {d}" for c, d in made) or "commit and date not recorded"
    total = sum(read(out, study, run, i).summary["wall_time_s"] for run, i in study.all_runs())
    wall = f", {total:.0f} s of runs"
    lines = [*described(study), "", textwrap.fill(f"Made by `{command(study)}` ({when}{wall}).", 100,
                                                break_on_hyphens=False), "",
             *TABLES[study.table](study, out)]
    return [begin(study), *"\n".join(lines).split("\n"), end(study)]


def not_run(study: Study) -> list[str]:
    lines = [*described(study), "", f"Not run yet: `{command(study)}`."]
    return [begin(study), *"\n".join(lines).split("\n"), end(study)]


def sections_of(text: str) -> dict[str, list[str]]:
    """The sections an earlier report holds, by study name."""
    found = {}
    for m in re.finditer(r"<!-- study: (\S+) -->\n(.*?)\n<!-- end of study: \1 -->", text, re.S):
        found[m.group(1)] = [f"<!-- study: {m.group(1)} -->", *m.group(2).split("\n"), f"<!-- end of study: {m.group(1)} -->"]
    return found


def report(out: Path, made: set[str], earlier: str = "") -> str:
    """The whole report: the studies in ``made`` and every study ``out`` holds complete rendered from their runs,
    the others as ``earlier`` has them (or "not run yet")."""
    kept = sections_of(earlier)
    lines = [HEADER]
    lines += [f"- [{s.title}](#{anchor(s.title)})" for s in STUDIES]
    for study in STUDIES:
        lines.append("")
        if study.name in made or complete(study, out):
            lines += rendered(study, out)
        else:
            lines += kept.get(study.name) or not_run(study)
    return "\n".join(lines) + "\n"


def anchor(title: str) -> str:
    """The anchor GitHub gives a heading.

    >>> anchor("The carotid-like artery, three cycles: adaptive steps")
    'the-carotid-like-artery-three-cycles-adaptive-steps'
    """
    return re.sub(r"[^\w\- ]", "", title.lower()).replace(" ", "-")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "studies" / "verification", help="the runs' folder")
    ap.add_argument("--doc", type=Path, default=ROOT / "docs" / "verification.md")
    ap.add_argument("--only", default="", help="comma list of studies to run (the others are kept)")
    ap.add_argument("--render", action="store_true", help="run nothing: render what OUT holds")
    ap.add_argument("--fresh", action="store_true", help="run again the runs OUT already holds")
    ap.add_argument("--list", action="store_true", help="print the studies and their runs")
    args = ap.parse_args(argv)
    names = [s.name for s in STUDIES]
    chosen = [n for n in args.only.split(",") if n] or ([] if args.render else names)
    unknown = [n for n in chosen if n not in names]
    if unknown:
        ap.error(f"--only: no study {', '.join(unknown)}; the studies are {', '.join(names)}")
    if args.list:
        for s in STUDIES:
            print(f"{s.name}: {s.case} {' '.join(s.sets)} ({len(s.runs)} runs × {s.repeat}"
                  + (", and a reference" if s.reference else "") + ")")
            for run, i in s.all_runs():
                if i == 0:
                    print(f"    {run.label}: {' '.join(run.sets)}")
        return 0
    made = set()
    if not args.render:
        for study in STUDIES:
            if study.name in chosen:
                run_study(study, args.out, args.fresh)
                made.add(study.name)
    earlier = args.doc.read_text() if args.doc.is_file() else ""
    args.doc.write_text(report(args.out, made, earlier))
    print(f"wrote {args.doc}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
