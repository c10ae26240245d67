"""Cycle summaries of a periodic load (multilayer.results.cycles, multilayer.results.shear, docs/readouts.md).

The pure functions against series whose answers are known exactly: pressures made of harmonics sampled where
their peaks are (systolic, diastolic, mean, pulse), an inflow of known integral (stroke volume), an area of
known swing (distensibility), TAWSS and OSI of a constant and of a pure oscillation, and a decaying transient
whose cycle-to-cycle change is a geometric series.  Then the carotid-like artery over two beats: the stroke
volume is the inflow table's integral over the beat, the pressures physiological, the run nearly periodic.
"""

import json

import numpy as np
import pytest
from runs import CASES, run_case_file

from multilayer import read_results
from multilayer.case.casefile import load_case
from multilayer.plugin.units import MMHG
from multilayer.results import cycles, shear
from multilayer.results.figures import plot_run
from multilayer.results.reading import position_column
from multilayer.runner import progress

T = 0.8
DT = T / 200


def times(n_cycles, dt=DT):
    return np.arange(1, round(n_cycles * T / dt) + 1) * dt


def test_pressures_stroke_volume_and_distensibility_of_a_synthetic_periodic_series():
    t = times(3)
    w = 2 * np.pi / T
    # 80 + 40 sin²(ωt/2)... as harmonics: p = P0 + P1 sin ωt + P2 cos 2ωt, max at ωt = π/2 (P0 + P1 − P2), min at
    # 3π/2 (P0 − P1 − P2) when P1 > 4 P2; both instants are rows (T/4, 3T/4 on a step of T/200)
    P0, P1, P2 = 1.2e5, 2.0e4, 2.0e3
    p = P0 + P1 * np.sin(w * t) + P2 * np.cos(2 * w * t)
    q = 6.0 + 9.0 * np.sin(w * t) + 1.5 * np.cos(3 * w * t)  # mL/s: ∫ over a beat = 6 T
    area = 0.3 * (1 + 0.05 * np.sin(w * t))
    summary = cycles.summarize(t, T, {"p_mid": (3.0, p), "end.outlet.p": (6.0, p - 1e4)}, q, {"eta_z2": (2.0, area)})
    assert [c["index"] for c in summary] == [0, 1, 2]
    for c in summary:
        s = c["pressure"]["p_mid"]
        assert s["systolic"] == pytest.approx(P0 + P1 - P2, rel=1e-14)
        assert s["diastolic"] == pytest.approx(P0 - P1 - P2, rel=1e-14)
        assert s["mean"] == pytest.approx(P0, rel=1e-14)  # the harmonics average out exactly on T/200 steps
        assert s["pulse"] == pytest.approx(2 * P1, rel=1e-13)
        assert s["systolic_mmHg"] == pytest.approx((P0 + P1 - P2) / 1333.22387415, rel=1e-14)
        assert c["pressure"]["end.outlet.p"]["mean"] == pytest.approx(P0 - 1e4, rel=1e-14)
        assert c["stroke_volume"] == pytest.approx(6.0 * T, rel=1e-13)
        d = c["distensibility"]["eta_z2"]
        assert d["pressure"] == "p_mid"  # the pressure nearest to z = 2
        assert d["value"] == pytest.approx((1.05 - 0.95) / (0.95 * 2 * P1), rel=1e-13)
        assert d["per_mmHg"] == pytest.approx(d["value"] * MMHG, rel=1e-15)
    assert "change" not in summary[0]
    assert all(abs(v) < 1e-12 for c in summary[1:] for v in c["change"].values())  # periodic: no change
    assert summary[2]["max_change"] < 1e-12


def test_the_change_from_cycle_to_cycle_of_a_decaying_transient_is_its_geometric_series():
    t, tau = times(4), 0.5
    decay = np.exp(-t / tau)
    p = 1e5 + 2e4 * np.sin(2 * np.pi * t / T) + 3e4 * decay
    summary = cycles.summarize(t, T, {"p": (0.0, p)})
    # the mean: (1/T) Σ over the cycle's rows of p Δt; the transient's part is a geometric sum
    n = round(T / DT)
    part = [3e4 * DT * np.exp(-(k * T + DT) / tau) * (1 - np.exp(-T / tau)) / (1 - np.exp(-DT / tau)) / T
            for k in range(4)]
    for k, c in enumerate(summary):
        assert c["pressure"]["p"]["mean"] == pytest.approx(1e5 + part[k], rel=1e-12)
    for k in range(1, 4):
        assert summary[k]["change"]["pressure.p.mean"] == pytest.approx((part[k] - part[k - 1]) / (1e5 + part[k - 1]),
                                                                        rel=1e-9)
    changes = [c["max_change"] for c in summary[1:]]
    assert changes[0] > changes[1] > changes[2] > 0  # the run settles into its periodic state
    assert n == 200


def test_cycles_are_those_the_steps_cover_whatever_the_steps():
    """Uneven steps that do not land on kT: the integral clips the steps that straddle a cycle's ends."""
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.5, 1.5, 1000) * DT)  # about 5 T
    assert cycles.windows(t, T) == [(k, k * T, (k + 1) * T) for k in range(int(t[-1] // T))]
    for k, a, b in cycles.windows(t, T):
        assert float(cycles.integral(t, np.ones_like(t), a, b)) == pytest.approx(T, rel=1e-13)
    # a series that has lost its first steps (a table begun later) has no cycle before its first row's step
    later = cycles.windows(t[t > 1.3 * T], T, start=t[t <= 1.3 * T][-1])
    assert later[0][0] == 2 and later == cycles.windows(t, T)[2:]
    assert cycles.windows(times(0.5), T) == [] and cycles.summarize(times(0.5), T, {}) == []


def test_tawss_and_osi_of_steady_reversing_and_oscillating_shear():
    t = times(2)
    w = 2 * np.pi / T
    wss = np.column_stack([np.full_like(t, 12.0), 5.0 * np.cos(w * t), 4.0 - 4.0 * np.cos(w * t), 0 * t])
    block = shear.summarize(t, np.array([0.0, 1.0, 2.0, 3.0]), wss, T)
    assert block["peak"] == pytest.approx([12.0, 5.0, 8.0, 0.0])
    last = block["cycles"][-1]
    # TAWSS: 12; 5·(2/π) (|cos| sampled on T/200: exact up to the kink, ~1e-5); 4 (never negative); 0
    assert last["tawss"][0] == pytest.approx(12.0, rel=1e-14)
    assert last["tawss"][1] == pytest.approx(10 / np.pi, rel=1e-4)
    assert last["tawss"][2] == pytest.approx(4.0, rel=1e-14)
    assert last["osi"][:3] == pytest.approx([0.0, 0.5, 0.0], abs=1e-14)
    assert last["osi"][3] is None  # no shear at all: undefined
    assert last["change"] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.slow
def test_the_carotid_over_two_beats_gives_its_cycle_summaries_and_wall_shear(tmp_path):
    """``cases/carotid.toml`` to t = 2 s (two beats; 20 × 3 cells to keep it short)."""
    case = load_case(CASES / "carotid.toml", ["time.end=2.0", "mesh.nz=20", "mesh.nr=3"])
    result, data = run_case_file("carotid", tmp_path, "time.end=2.0", "mesh.nz=20", "mesh.nr=3")
    assert result.status == "ok", result.reason
    summary = data.summary
    block = summary["cycles"]
    assert block["period"] == 1.0 and block["units"]["stroke_volume"] == "mL"
    beats = block["cycles"]
    assert [(c["index"], c["start"], c["end"]) for c in beats] == [(0, 0.0, 1.0), (1, 1.0, 2.0)]
    # the stroke volume is the inflow table's integral over the beat: the flow-rate inlet prescribes the flux of
    # each step (measured to 1.4e-12 on the 30 × 4 mesh)
    inflow = case.loads.inlet.histories()[0]
    assert beats[1]["stroke_volume"] == pytest.approx(inflow.integral(1.0, 2.0), rel=1e-9)
    for name in ("p_in", "p_mid", "p_out", "end.inlet.p", "end.outlet.p"):
        p = beats[1]["pressure"][name]
        assert 100 < p["systolic_mmHg"] < 140 and 60 < p["diastolic_mmHg"] < 90, (name, p)
        assert p["diastolic"] < p["mean"] < p["systolic"]
    for name in ("eta_z1", "eta_z3", "eta_z5", "eta_z55"):
        d = beats[1]["distensibility"][name]
        assert 1e-3 < d["per_mmHg"] < 1e-2, (name, d)  # a carotid's 2–6e-3 /mmHg
    assert beats[1]["distensibility"]["eta_z3"]["pressure"] == "p_mid"
    assert 0.0 < beats[1]["max_change"] < 0.1  # the Windkessel still settles in its second beat
    # the wall shear stress: TAWSS of the beat and OSI (the inflow never reverses: no oscillation)
    wss = summary["wss"]
    assert len(wss["z"]) == 21 and len(wss["cycles"]) == 2
    tawss, osi = np.array(wss["cycles"][1]["tawss"]), np.array(wss["cycles"][1]["osi"])
    assert np.all((tawss > 5.0) & (tawss < 60.0)), tawss  # dyn/cm²
    assert np.all((osi >= 0.0) & (osi < 0.05)), osi
    # clean headers in both lumen tables (z = 0.3 k, no 0.30000000000000004)
    for name in ("eta_lumen.csv", "wss_lumen.csv"):
        header = (tmp_path / name).read_text().splitlines()[0].split(",")
        assert header[2:] == [position_column(0.3 * k) for k in range(21)] and "z=0.9" in header
    # the Python API and the figures
    res = read_results(tmp_path)
    assert res.cycles == beats and res.period == 1.0 and res.wall_shear == wss
    assert res.wss_lumen[2].shape == (2000, 21) and np.array_equal(res.wss_lumen[0], res.eta_lumen[0])
    # the pulse-wave velocity foot to foot between p_in, p_mid and p_out, of a carotid's order (4–10 m/s); its loop
    speed = beats[1]["pulse_wave_velocity"]
    assert speed["value"] is not None and 4.0 < speed["m_s"] < 10.0, speed
    assert list(speed["feet"]) == ["p_in", "p_mid", "p_out"]
    assert {p.name for p in plot_run(tmp_path)} >= {"wss.png", "cycles.png", "pressure_diameter.png", "pulse_wave.png"}
    assert json.loads((tmp_path / "summary.json").read_text())["cycles"] == block
    # the run's closing lines: the last beat, its pressures in mmHg, its stroke volume and its change
    assert result.cycles == block
    line = progress.summary(result, 1.0, tmp_path).splitlines()[-2]
    p = beats[1]["pressure"]["p_out"]
    assert line.startswith("  cycle 2 (1–2 s): p_in ") and "end.outlet" not in line, line
    assert f"p_out {p['systolic_mmHg']:.4g}/{p['diastolic_mmHg']:.4g} (mean {p['mean_mmHg']:.4g}) mmHg" in line
    assert f"stroke volume {beats[1]['stroke_volume']:.4g} mL" in line
    assert f"; pulse-wave velocity {speed['m_s']:.3g} m/s (foot to foot); " in line
    assert line.endswith(f"within {100 * beats[1]['max_change']:.2g} % of cycle 1"), line


def test_a_run_in_memory_has_the_same_cycles_and_wall_shear_as_its_folder(tmp_path):
    """The summary blocks come from the tables the run wrote: held in memory or read back from the folder."""
    import multilayer as ml

    case = ml.load_case(CASES / "pulse-koiter-thick.toml", {
        "mesh.nz": 12, "mesh.nr": 3, "time.end": 0.006,
        "loads.inlet": {"model": "sine", "amplitude": 2e3, "frequency": 500.0, "mean": 1e3}})
    held, saved = ml.run(case), ml.run(case, tmp_path)
    assert held.period == saved.period == pytest.approx(2e-3)
    assert [c["index"] for c in held.cycles] == [0, 1, 2]
    assert held.cycles == saved.cycles and held.wall_shear == saved.wall_shear
    assert all(np.array_equal(a, b) for a, b in zip(held.wss_lumen, saved.wss_lumen))
    inlet = held.cycles[2]["pressure"]["end.inlet.p"]  # the inlet's pressure: the step means of the sine
    assert inlet["mean"] == pytest.approx(1e3, rel=1e-12) and inlet["pulse"] == pytest.approx(4e3, rel=0.05)


def travelling(t, z, c, period=1.0):
    """A periodic pulse running downstream at c (cm/s): at each beat a half sine from 0.1 s after its start at
    z = 0, 0.3 s long, on 80 mmHg; the foot at z is 0.1 + z/c into the beat."""
    s = np.mod(t - z / c, period)
    return (80.0 + 40.0 * np.maximum(0.0, np.sin(np.pi * (s - 0.1) / 0.3)) * (s > 0.1)) * MMHG


@pytest.mark.parametrize("dt", (1e-3, 5e-4))
def test_the_pulse_wave_velocity_of_a_travelling_pulse_is_its_speed(dt):
    """Foot to foot between three pressures of a pulse p(t − z/c) over three beats gives c in every beat: to
    round-off where the transit times are whole steps (c = 500 cm/s, probes 2 cm apart, Δt = 1 and 0.5 ms), and
    within a tolerance that falls with Δt where they are not (c = 600 cm/s: transits of 3.33 ms; the tangents'
    feet, through the rows' secants).

    Measured (last beat): c = 600 within 5.1e-6 (Δt = 1 ms) and 6.3e-7 (0.5 ms) relatively."""
    t = np.arange(1, round(3.0 / dt) + 1) * dt
    for c, tolerance in ((500.0, 1e-9), (600.0, 1e-5 * (dt / 1e-3) ** 2)):
        waves = {f"p_{z:g}": (z, travelling(t, z, c)) for z in (1.0, 3.0, 5.0)}
        beats = cycles.summarize(t, 1.0, waves, waves=waves)
        for beat in beats:
            speed = beat["pulse_wave_velocity"]
            assert speed["value"] == pytest.approx(c, rel=tolerance), (c, dt, speed)
            assert speed["m_s"] == pytest.approx(speed["value"] / 100.0, rel=1e-15)
            for z in (1.0, 3.0, 5.0):  # the foot 0.1 s into the beat at z = 0, then z/c later
                foot = speed["feet"][f"p_{z:g}"]
                assert foot["z"] == z and foot["time"] == pytest.approx(beat["start"] + 0.1 + z / c, abs=0.05 * dt)
    print(f"Δt = {dt:g}: c = 600 within {abs(beats[-1]['pulse_wave_velocity']['value'] / 600.0 - 1):.2g}")


def test_no_pulse_wave_velocity_without_a_foot_and_its_reason():
    """A pressure that does not rise at one probe leaves one foot: no speed, and the reason says which."""
    t = np.arange(1, 2001) * 1e-3
    waves = {"p_1": (1.0, travelling(t, 1.0, 500.0)), "p_3": (3.0, np.full_like(t, 80.0 * MMHG))}
    speed = cycles.summarize(t, 1.0, waves, waves=waves)[-1]["pulse_wave_velocity"]
    assert speed["value"] is None and speed["m_s"] is None
    assert "fewer than two probes with a foot" in speed["reason"] and "p_3" in speed["reason"]
    assert speed["feet"]["p_3"]["time"] is None


def test_a_pressure_diameter_loop_returns_its_extremes_in_mmhg_and_mm():
    """p = 100 + 20 sin ωt mmHg, η = 0.01 sin(ωt − 0.3) cm at R = 0.3 cm, 200 rows a beat (the extremes on rows):
    the loop over the second beat runs 80 to 120 mmHg and 5.8 to 6.2 mm, and lags (an open loop)."""
    t = np.arange(1, 401) * 0.01
    w = 2 * np.pi
    p, eta = (100 + 20 * np.sin(w * t)) * MMHG, 0.01 * np.sin(w * t - 0.3)
    loop = cycles.pressure_diameter(t, p, eta, 0.3, 1.0, 2.0, 1.0)
    assert len(loop["pressure"]) == len(loop["diameter"]) == 100
    assert loop["pressure_min"] == pytest.approx(80.0, rel=1e-12) and loop["pressure_max"] == pytest.approx(120.0)
    assert loop["diameter_min"] == pytest.approx(5.8, rel=1e-3) and loop["diameter_max"] == pytest.approx(6.2, rel=1e-3)
    # the loop's area ∮ p dD ≠ 0: diameter and pressure are out of phase
    area = np.sum(0.5 * (loop["pressure"][1:] + loop["pressure"][:-1]) * np.diff(loop["diameter"]))
    assert abs(area) > 1.0
