"""Adaptive steps (``[time] tolerance``): the ledger closes with changing Δt, rejected steps leave no trace,
steps land on the output times, dt_min stops the run with its rows kept, and resume is bit-identical.

Sizes: the quick-start pulse (Koiter shell on a thick band) on a coarse mesh (nz = 12, nr = 3), 4 ms.
"""

import math
from types import SimpleNamespace

import attrs
import numpy as np
import pytest
from runs import CASES, assert_resume_is_bit_identical, run_cli

from multilayer.case.casefile import load_case
from multilayer.case.model import TimeSpec
from multilayer.coupling.clock import Adaptive
from multilayer.functions.loads import CosinePulse, SinePressure, TablePressure
from multilayer.numerics.stepsize import Controller, local_error, predictor
from multilayer.numerics.timescheme import named
from multilayer.runner.loop import run_case
from multilayer.runner.progress import ProgressBar

SMALL = ("mesh.nz=12", "mesh.nr=3", "time.end=0.004", "time.dt=1e-6")
MONOLITHIC = 'coupler={model="monolithic",scheme="crank-nicolson"}'
SPLITTING = 'coupler={model="kinematic-splitting",scheme="crank-nicolson",beta=1,robin="inertia"}'
PER_UNIT_STEP = 'time.control="per-unit-step"'
#: the tolerance each coupler is tested at
TOLERANCE = {MONOLITHIC: "1e-3", SPLITTING: "1e-3"}


def test_the_predictor_is_exact_for_quadratics_and_the_estimate_for_cubics_on_uneven_steps():
    """x = t² is predicted exactly; for x = t³/6 the scaled difference is the CN local error k³/12."""
    k = [0.3, 0.1, 0.2]
    t = np.array([0.6, 0.3, 0.2, 0.0])
    assert math.isclose(float(predictor(list(t[1:] ** 2), k)), 0.36, rel_tol=1e-12)
    xs = t ** 3 / 6
    estimate = local_error(xs[0] + k[0] ** 3 / 12, list(xs[1:]), k, named("crank-nicolson"))
    assert math.isclose(float(estimate), k[0] ** 3 / 12, rel_tol=1e-12)


def test_the_controller_grows_after_a_small_error_and_shrinks_after_a_large_one():
    c = Controller()
    assert c.accepted(1e-3, 1e-3)[0] == 2.0 and c.accepted(1.0, 1.0)[0] < 1.0 and c.rejected(100.0) == 0.1
    held = Controller(3, hold=True)  # per-step control: growth below KEEP is held back until it reaches KEEP
    assert held.accepted(0.1, 0.1) == (1.0, pytest.approx(1.133, abs=1e-3))
    assert held.accepted(0.1, 0.1, 1.133)[0] == pytest.approx(1.2838, abs=1e-4)


@pytest.mark.parametrize("coupler, tolerance", TOLERANCE.items())
def test_adaptive_steps_close_the_ledger_and_report_their_steps(tmp_path, coupler, tolerance):
    """Changing Δt: CN's identity holds step by step with that step's Δt, so the ledger closes to round-off
    (measured ≤ 2e-12); every rejected try is dropped whole (the ledger would not close otherwise)."""
    code, summary, rows = run_cli("pulse-koiter-thick", tmp_path / "a", *SMALL, coupler,
                                  f"time.tolerance={tolerance}", "time.output_interval=1e-3")
    assert code == 0 and summary["status"] == "ok", summary["reason"]
    assert summary["energy"]["max_relative_residual"] < 1e-9
    adaptive = summary["adaptive"]
    assert adaptive["control"] == "per-step" and adaptive["size"] == "so-far"  # the defaults
    assert adaptive["accepted"] == summary["steps"] == len(rows)
    dts = np.array([float(r["dt"]) for r in rows])
    t = np.array([float(r["t"]) for r in rows])
    assert len(set(dts)) > 10 and adaptive["dt_range"] == [dts.min(), dts.max()]
    assert np.allclose(np.cumsum(dts), t, rtol=1e-12, atol=0.0)
    assert all(float(r["error.local"]) <= 1.0 for r in rows)
    landed = [float(r["t"]) for r in rows if float(r["landed"])]
    assert landed == pytest.approx([0.001, 0.002, 0.003, 0.004], rel=1e-12)
    assert t[-1] == 0.004


def test_a_step_below_dt_min_stops_the_run_and_keeps_its_rows(tmp_path):
    code, summary, rows = run_cli("pulse-koiter-thick", tmp_path / "a", *SMALL, MONOLITHIC,
                                  "time.tolerance=1e-8", "time.dt_min=5e-7")
    assert code != 0 and summary["status"] == "failed"
    assert "time.dt_min" in summary["reason"] and "every step before is kept" in summary["reason"]
    assert len(rows) == summary["steps"] >= 2


@pytest.mark.parametrize("coupler", [MONOLITHIC, SPLITTING], ids=["monolithic-cn", "splitting-cn-beta1"])
def test_an_adaptive_run_resumed_from_its_checkpoint_is_bit_identical(tmp_path, coupler):
    """The controller's record (proposal, last error, peaks, counts, the per-step count N_W) is the state's
    ``extra['clock']`` and Crank–Nicolson's last estimates its ``extra['echo.*']``, so a checkpoint carries them,
    and the wall's reusing solver's held factors (the splitting's) too; the share of the tolerance is counted
    over the elapsed time (not time.end), so a run to 2 ms resumed to 4 ms takes the steps of a run to 4 ms."""
    assert_resume_is_bit_identical(tmp_path, "pulse-koiter-thick", "mesh.nz=12", "mesh.nr=3", "time.dt=1e-6",
                                   coupler, f"time.tolerance={TOLERANCE[coupler]}", "time.output_interval=1e-3",
                                   every=10, half=0.002, end=0.004)


def test_steps_land_on_the_output_times_without_a_sliver():
    """Two equal steps instead of one step and a sliver before an output time."""

    clock = clock_for(TimeSpec(end=1.0, dt=0.1, tolerance=1e-3, dt_min=1e-9, output_interval=0.25))

    class State:
        t, n, previous = 0.2, 2, None

        @classmethod
        def history(cls, levels):
            return [cls] * levels

    w = clock.window(State, 0.04)  # 0.24 would leave a sliver of 0.01 before 0.25: two halves instead
    assert math.isclose(w.dt, 0.025) and math.isclose(w.t1, 0.225)
    w = clock.window(State, 0.02)
    assert math.isclose(w.t1, 0.22)
    w = clock.window(State, 0.06)  # beyond the output time: clipped onto it
    assert w.t1 == 0.25


def clock_for(time, *loads):
    """The adaptive clock of a case with ``time`` whose only loads are ``loads`` (a Crank–Nicolson scheme)."""
    setup = SimpleNamespace(case=SimpleNamespace(time=time, loads=SimpleNamespace(histories=lambda: loads)))
    return Adaptive(setup, named("crank-nicolson"))


def test_a_study_puts_adaptive_and_fixed_runs_on_one_front(tmp_path):
    """``--vary time.tolerance=none,...``: fixed-Δt runs (none) and adaptive ones against one reference; the
    adaptive ones get a calibration table (error / tolerance) and ``tolerance.png``, all are on the front."""
    import json

    from runs import CASES

    from multilayer.commands.main import main

    out = tmp_path / "study"
    code = main(["study", str(CASES / "pulse-koiter-thick.toml"), "--out", str(out),
                 "--couplers", '{model="monolithic",scheme="crank-nicolson"}',
                 "--set", "mesh.nz=12", "--set", "mesh.nr=3", "--set", "time.end=0.002",
                 "--vary", "time.tolerance=none,1e-2,1e-3", "--set", "time.dt=1e-5",
                 "--reference-set", "time.dt=2.5e-6", "--probes", "eta_z1"])
    assert code == 0
    data = json.loads((out / "study.json").read_text())
    rows = {r["label"]: r for r in data["runs"]}
    assert sorted(r["tolerance"] for r in rows.values() if r["tolerance"]) == [1e-3, 1e-2]
    assert [a["tolerance"] for a in data["adaptive"]] == [1e-2, 1e-3]
    assert all(a["error"] is not None and a["ratio"] == a["error"] / a["tolerance"] for a in data["adaptive"])
    assert set(data["pareto"]) <= set(rows) and "## Adaptive steps" in (out / "study.md").read_text()


#: the light wall's tolerances: the splitting's steps there are set by its splitting error (1e-1: 3 714 steps over
#: 0.05 s, 3e-1: 2 159, the fewest above the 2 000 that dt_max asks for anyway)
LIGHT = {MONOLITHIC: "1e-3", SPLITTING: "3e-1"}


@pytest.mark.parametrize("coupler, control", [(MONOLITHIC, ()), (SPLITTING, ()), (MONOLITHIC, (PER_UNIT_STEP,))],
                         ids=["monolithic-cn", "splitting-cn-beta1", "monolithic-cn-per-unit-step"])
def test_adaptive_steps_are_stable_at_the_lightest_wall(tmp_path, coupler, control):
    """ρ₁h/(ρ_f R) = 1e-3 (the light-wall scene of tests/test_coupled.py), adaptive steps capped at
    dt_max = 2.5e-5 over 0.05 s, so at least 2000 accepted steps: energy ≤ initial (0, from rest) + work at
    every step, the ledger closed at every step (measured: monolithic at tol 1e-3 2 307 accepted steps, the
    splitting at tol 3e-1 2 025, monolithic per unit step 2 254; max (E − W)/max|W| ≤ −6.3e-25, residual
    ≤ 1.9e-12; over 0.2 s with dt_max = 1e-4 monolithic took 4 129 steps, the splitting at 1e-2 28 335,
    monolithic per unit step 3 262)."""
    code, summary, rows = run_cli(
        "pulse-koiter", tmp_path / "light",
        'layers[0]={ model = "koiter-shell", density = 1.0, thickness = 0.0005, young = 7.5e7, poisson = 0.49 }',
        "geometry.length=2.0", "mesh.nz=8", "mesh.nr=2", "time.end=0.05", "time.dt=1e-6", "time.dt_max=2.5e-5",
        f"time.tolerance={LIGHT[coupler]}", "output.probes=[{ name = \"eta_z1\", quantity = \"eta\", z = 1.0 }]",
        coupler, *control, "solver.volume_margin=2")  # the paper's splitting drifts in volume (theory §7)
    assert code == 0 and summary["status"] == "ok", summary["reason"]
    assert summary["adaptive"]["accepted"] == len(rows) >= 2000
    energy = np.array([float(r["energy.total"]) for r in rows])
    work = np.cumsum([sum(float(v) for k, v in r.items() if k.startswith("work.")) for r in rows])
    assert np.all(energy <= work + 1e-9 * np.max(np.abs(work)))
    assert max(float(r["energy.relative_residual"]) for r in rows) <= 1e-9


def test_the_error_per_unit_time_is_measured_over_the_memory_time():
    """W is time.memory, else the loads' shortest period, else time.end; a field's size counts its rate over
    min(t, W), and the normalized error of a step is e · min(t, W) / (Δt · tol)."""
    time = TimeSpec(end=1.0, dt=1e-3, tolerance=1e-2)
    assert clock_for(time).memory == 1.0
    assert clock_for(time, SinePressure(1.0, 4.0), SinePressure(1.0, 10.0)).memory == 0.1
    clock = clock_for(attrs.evolve(time, memory=0.25, size="so-far"), SinePressure(1.0, 10.0))
    assert clock.memory == 0.25
    x, before = np.array([1.0, -3.0]), np.array([1.0, -2.0])
    assert clock.size(x, before, 0.1, 0.01) == 10.0  # t < W: t |Δx|/Δt
    assert clock.size(x, before, 2.0, 0.01) == 25.0  # t > W: W |Δx|/Δt


def test_a_fields_size_over_the_memory_time_counts_its_rate_over_w_and_forgets_its_peak():
    """time.size = "memory" (a periodic load's default): the rate term is W |Δx|/Δt from the first step (the first
    period measured as the later ones), and the peak decays by exp(−Δt/W) a step, as N_W forgets its steps;
    "so-far" keeps the peak."""
    time = TimeSpec(end=3.0, dt=1e-3, tolerance=1e-2)
    x, before = np.array([1.0, -3.0]), np.array([1.0, -2.0])
    so_far, memory = clock_for(attrs.evolve(time, size="so-far"), SinePressure(1.0, 4.0)), clock_for(time,
                                                                                                    SinePressure(1.0, 4.0))
    assert clock_for(time).over_memory is False  # no periodic load: "so-far" by default
    assert so_far.size(x, before, 0.1, 0.01) == pytest.approx(10.0)  # t < W = 0.25: t |Δx|/Δt
    assert memory.size(x, before, 0.1, 0.01) == pytest.approx(25.0)  # W |Δx|/Δt
    assert memory.size(x, before, 2.0, 0.01) == so_far.size(x, before, 2.0, 0.01) == pytest.approx(25.0)
    assert so_far.forgetting(0.05) == 1.0 and memory.forgetting(0.05) == pytest.approx(np.exp(-0.2))
    peak = 1.0
    for _ in range(50):  # one W of steps of W/50: the peak falls to 1/e
        peak *= memory.forgetting(0.005)
    assert peak == pytest.approx(np.exp(-1.0), rel=1e-12)


def test_steps_land_on_a_tables_rows_and_a_pulses_end():
    """A linear table's slope jumps at every row, a cosine pulse's curvature at its end: a step stops there."""
    time = TimeSpec(end=1.0, dt=1e-3, tolerance=1e-2)
    table = TablePressure(np.array([0.0, 0.1, 0.3]), np.array([1.0, 2.0, 0.0]), period=0.4)
    clock = clock_for(time, table, CosinePulse(1.0, 0.55))

    class State:
        t, n, previous = 0.42, 5, None

        @classmethod
        def history(cls, levels):
            return [cls] * levels

    assert clock.landing(0.42) == pytest.approx(0.5) and clock.window(State, 0.2).t1 == clock.landing(0.42)
    assert clock.landing(0.5) == pytest.approx(0.55)  # the pulse's end comes before the next row (0.7)
    assert clock.landing(0.55) == pytest.approx(0.7)
    assert clock.window(State, 0.05).t1 == pytest.approx(0.46)  # 0.47 would leave a sliver: two halves


def test_an_adaptive_run_on_a_periodic_table_lands_on_every_row(tmp_path):
    """The physiological waveform (a table every 1e-4 s, linear): no step straddles a row, and the rows marked
    ``landed`` are the output times only (the end here)."""
    code, summary, rows = run_cli("physiological-waveform", tmp_path / "a", "mesh.nz=12", "mesh.nr=3",
                                  "time.end=0.002", MONOLITHIC, "time.tolerance=1e-2", "time.dt=1e-5")
    assert code == 0 and summary["status"] == "ok", summary["reason"]
    assert summary["adaptive"]["memory"] == 0.02  # the table's period
    t = np.array([float(r["t"]) for r in rows])
    gaps = np.abs(t[None, :] - 1e-4 * np.arange(1, 21)[:, None]).min(axis=1)
    assert gaps.max() < 1e-15 and len(t) > 20
    assert [float(r["t"]) for r in rows if float(r["landed"])] == [0.002]


class _Level:
    """A level of a run as :meth:`KinematicSplitting.estimate` reads it: n, t, wall.d, extra, history."""

    def __init__(self, n, t, d, extra, previous=None):
        self.n, self.t, self.extra, self.previous = n, t, extra, previous
        self.wall = type("Wall", (), {"d": np.array(d, dtype=float)})

    def history(self, levels):
        out = [self]
        while len(out) < levels:
            out.append(out[-1].previous or out[-1])
        return out


def test_the_splitting_estimate_sees_its_smooth_defect_and_not_the_alternating_one():
    """One lumen DOF (P = R = 1) on uneven steps.  η − Z = t³/6 with Z of a (−1)ⁿ rate: the Crank–Nicolson part is
    the estimate of t³/6 alone (k³/12 for its CN value); the next-step part of a rate c(−1)ⁿ is 0 whatever the
    steps, and of a constant rate c is k·c."""
    from multilayer.coupling.clock import Window
    from multilayer_plugins.kinematic_splitting import KinematicSplitting

    k = [0.3, 0.1, 0.2]
    t = [0.0, 0.2, 0.3, 0.6]
    rates = [np.array([0.5 * (-1) ** n]) for n in range(4)]
    z = np.cumsum([0.0, *(dt * r[0] for dt, r in zip(np.diff(t), rates[1:]))])
    levels = None
    for n in range(3):  # the old levels: η = t³/6 + Z (their CN values do not matter: the predictor is on them)
        levels = _Level(n, t[n], [t[n] ** 3 / 6 + z[n]],
                        {"splitting.Z": np.array([z[n]]), "splitting.rate": rates[n]}, levels)
    one = np.eye(1)
    d_new = np.array([t[3] ** 3 / 6 + k[0] ** 3 / 12 + z[3]])
    out = KinematicSplitting.estimate(levels, Window(2, t[2], t[3], k[0], named("crank-nicolson")), d_new, one, one, rates[3])
    assert math.isclose(float(out["estimate.wall.d"][0]), k[0] ** 3 / 12, rel_tol=1e-9)
    assert out["estimate.next.wall.d"][0] == 0.0 and math.isclose(float(out["splitting.Z"][0]), z[3], rel_tol=1e-12)
    steady = {**levels.extra, "splitting.rate": np.array([0.5])}
    levels = _Level(levels.n, levels.t, levels.wall.d, steady, levels.previous)
    out = KinematicSplitting.estimate(levels, Window(2, t[2], t[3], k[0], named("crank-nicolson")), d_new, one, one, np.array([0.5]))
    assert math.isclose(float(out["estimate.next.wall.d"][0]), k[0] * 0.5, rel_tol=1e-12)


def test_the_splittings_start_at_1e_5_goes_through_per_step_and_stops_at_dt_min_per_unit_step(tmp_path):
    """The remnant of the first steps gives the splitting's defect a rate no shorter step reduces: per unit step
    its err, kₙ|V̄_Γ − v̄| t/(kₙ tol), does not fall and the run stops at dt_min at t ≈ 2.0e-6 s; per step,
    kₙ|V̄_Γ − v̄| N_W/tol does, and the steps recover (measured: 884 steps to 1e-5 s, down to 6.4e-10 s)."""
    sets = ("mesh.nz=12", "mesh.nr=3", "time.end=1e-5", SPLITTING, "time.tolerance=1e-5", "time.dt=1e-6")
    code, summary, rows = run_cli("pulse-koiter-thick", tmp_path / "step", *sets)
    assert code == 0 and summary["status"] == "ok", summary["reason"]
    assert summary["adaptive"]["dt_range"][0] < 1e-8 and summary["energy"]["max_relative_residual"] < 1e-9
    code, summary, rows = run_cli("pulse-koiter-thick", tmp_path / "unit", *sets, PER_UNIT_STEP)
    assert code != 0 and summary["status"] == "failed" and "time.dt_min" in summary["reason"]
    assert float(rows[-1]["t"]) < 3e-6 and len(rows) == summary["steps"]


@pytest.mark.parametrize("control", [(), (PER_UNIT_STEP,)], ids=["per-step", "per-unit-step"])
def test_the_splittings_error_is_within_3x_of_its_tolerance_over_a_decade(tmp_path, control):
    """The calibration of docs/verification.md (adaptive steps) on a coarse pulse (12 × 3 cells, 4 ms; η at z = 1, 2 cm against
    monolithic CN at Δt = 2.5e-6): the relative L∞ error over the tolerance, measured per step (its next-step
    error under a PI controller of its own, q = 1) 0.64 at 1e-2 and 0.65 at 1e-3 — with the step's q = 3 it was
    0.32 at 1e-2, outside the band; per unit step 1.07 and 1.07; the acceptance's band is [1/3, 3]."""
    from multilayer.campaign.accuracy import probe_errors
    from multilayer.results.reading import read_run

    sets = ("mesh.nz=12", "mesh.nr=3", "time.end=0.004")
    code, _, _ = run_cli("pulse-koiter-thick", tmp_path / "ref", *sets, MONOLITHIC, "time.dt=2.5e-6")
    assert code == 0
    ref = read_run("ref", tmp_path / "ref")
    for tolerance in (1e-2, 1e-3):
        out = tmp_path / f"tol{tolerance}"
        code, summary, _ = run_cli("pulse-koiter-thick", out, *sets, SPLITTING, "time.dt=1e-6",
                                   f"time.tolerance={tolerance}", *control)
        assert code == 0 and summary["status"] == "ok", summary["reason"]
        run = read_run(out.name, out)
        error = max(probe_errors(run.t, run.series[p], ref.t, ref.series[p])["relative_linf"]
                    for p in ("eta_z1", "eta_z2"))
        assert 1 / 3 <= error / tolerance <= 3, (tolerance, error)



def test_per_step_control_shares_the_tolerance_among_the_steps_of_the_memory_time():
    """Per-step control (the default): err = e · N_W / tol with N_W the steps of the last W — for even steps the
    per-unit-step allowance e · min(t, W)/(Δt · tol), exactly; the controller's error goes as Δt³ (per unit step
    as Δt²)."""
    from multilayer.coupling.clock import steps_in_memory
    time = TimeSpec(end=1.0, dt=1e-3, tolerance=1e-2, memory=0.5)
    step, unit = clock_for(time), clock_for(attrs.evolve(time, control="per-unit-step"))
    assert unit.controller.order == 2 and step.controller.order == 3
    record = {"steps_in_memory": 0.0}
    for n in range(1, 1001):  # even steps of 1e-3 to t = 1: 500 steps in W = 0.5, before and after t = W
        record["steps_in_memory"] = steps_in_memory(record, n * 1e-3, 1e-3, 0.5)
        if n in (100, 500, 1000):
            assert math.isclose(record["steps_in_memory"], min(n * 1e-3, 0.5) / 1e-3, rel_tol=1e-9)
    # an older record without the count: every accepted step so far
    assert steps_in_memory({"accepted": 7}, 0.1, 1e-3, 0.5) == 8.0


def test_crank_nicolsons_estimate_of_the_alternating_mode_depends_on_the_step_ratios_alone():
    """μ of (−1)ⁿ: −8/13 on even steps; −18/7 when the step doubles (Milne factor 1/7, predictor's miss 18)."""
    from multilayer.coupling.clock import alternating
    cn = named("crank-nicolson")
    assert math.isclose(alternating([0.1, 0.1, 0.1], cn), -8.0 / 13.0, rel_tol=1e-12)
    assert math.isclose(alternating([0.2, 0.1, 0.1], cn), -18.0 / 7.0, rel_tol=1e-12)
    assert math.isclose(alternating([2e-3, 1e-3, 1e-3], cn), -18.0 / 7.0, rel_tol=1e-12)


def test_the_unechoed_estimate_drops_an_alternating_mode_and_keeps_a_smooth_error():
    """Crank–Nicolson's estimate of x = t³/6 (smooth) is kept (exactly on even steps, 0.78–1.10 of it at step
    ratios 2–0.8, 1.4 at 0.5: larger, so smaller steps, where they shrink fast); that of the undamped stiff mode A(−1)ⁿ, which the plain estimate sees at every step (8A/13 for
    even steps), is 0 on any steps."""
    from multilayer.coupling.clock import unechoed
    cn = named("crank-nicolson")

    def estimates(x, steps):  # the plain estimate of the last step and of the one before, on ``steps`` (oldest first)
        t = np.concatenate([[0.0], np.cumsum(steps)])[::-1]
        k = list(np.diff(t[::-1])[::-1])
        values = [np.array([x(tt)]) for tt in t]
        return [(local_error(values[i], values[i + 1:i + 4], k[i:i + 3], cn), k[i:i + 3]) for i in (1, 0)]

    def filtered(pair):
        (e_before, k_before), (e_now, k_now) = pair
        return float(unechoed(e_now, unechoed(e_before, None, k_before, cn)[1], k_now, cn)[0][0]), float(e_now[0])

    h = 0.01
    for ratio, low, high in ((1.0, 1.0, 1.0), (2.0, 0.78, 0.79), (1.2, 0.92, 0.94), (0.8, 1.10, 1.11), (0.5, 1.39, 1.41)):
        got, plain = filtered(estimates(lambda t: t ** 3 / 6, [h, h, h, h, ratio * h]))
        assert low - 1e-9 <= got / plain <= high + 1e-9, (ratio, got / plain)
    sign = {}
    for steps in ([h] * 5, [h, 1.3 * h, 0.7 * h, h, 2.0 * h]):
        pair = estimates(lambda t, steps=steps: (-1.0) ** int(np.argmin(np.abs(np.cumsum([0.0, *steps]) - t))),
                         steps)
        got, plain = filtered(pair)
        sign[len(sign)] = plain
        assert abs(got) < 1e-12 * abs(plain)
    assert math.isclose(abs(sign[0]), 8.0 / 13.0, rel_tol=1e-12)


def test_per_unit_step_adaptive_runs_close_the_ledger_and_resume_bit_identically(tmp_path):
    """``time.control = "per-unit-step"``: the ledger closes, the summary names the control, and a resumed run
    takes the same steps (its controller's record is the state's, as per step)."""
    code, summary, rows = run_cli("pulse-koiter-thick", tmp_path / "a", *SMALL, MONOLITHIC, "time.tolerance=1e-3",
                                  PER_UNIT_STEP, "time.output_interval=1e-3")
    assert code == 0 and summary["status"] == "ok", summary["reason"]
    assert summary["adaptive"]["control"] == "per-unit-step"
    assert summary["energy"]["max_relative_residual"] < 1e-9
    assert all(float(r["error.local"]) <= 1.0 for r in rows)
    assert len({float(r["dt"]) for r in rows}) > 10
    assert_resume_is_bit_identical(tmp_path / "resume", "pulse-koiter-thick", "mesh.nz=12", "mesh.nr=3",
                                   "time.dt=1e-6", MONOLITHIC, "time.tolerance=1e-3", PER_UNIT_STEP,
                                   "time.output_interval=1e-3", every=10, half=0.002, end=0.004)


def test_the_progress_bar_counts_simulated_time(tmp_path):
    """The bar's total is ``time.end`` in seconds and it stands at each step's t: an adaptive run, whose number of
    steps is not known ahead, fills it exactly (a bar of steps would end at an arbitrary fraction)."""
    bar, seen = ProgressBar(0.002, enabled=True), []  # (on stderr, captured)

    def progress(tally, row):
        bar(tally, row)
        seen.append((bar.bar.n, tally.t, tally.steps))

    case = load_case(CASES / "pulse-koiter-thick.toml", [*SMALL[:2], "time.end=0.002", "time.dt=1e-6", MONOLITHIC,
                                                         "time.tolerance=1e-3"])
    assert run_case(case, tmp_path / "run", progress=progress).status == "ok"
    assert bar.bar.total == 0.002 and all(n == pytest.approx(t, rel=1e-12) for n, t, _ in seen)
    assert seen[-1][0] == pytest.approx(0.002, rel=1e-12)
    assert seen[-1][2] > 50  # many more steps than the 0.002 s the bar counts
