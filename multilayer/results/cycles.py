"""What a run under a periodic load gives per cardiac cycle, from its series alone (pure numpy).

A run's rows are at the ends of its steps t₁ < t₂ < …, the steps starting
at t₀ = ``start`` (0 for every run); row i stands for the step (tᵢ₋₁, tᵢ].
Cycle k is [kT, (k + 1)T]; it is *complete* when the steps cover it.  Over
a cycle [a, b] a series v has

* the time integral ∫ v dt = Σᵢ vᵢ |(tᵢ₋₁, tᵢ] ∩ [a, b]| (the step's mean
  times the part of the step in the cycle: exact for the columns that are
  step means, ``end.<end>.p``, ``end.<end>.Q``, and, for samples of a
  periodic signal at steps that tile the cycle, the trapezoidal rule);
* its maximum and minimum over the rows with a < tᵢ ≤ b.

From them, per complete cycle (:func:`summarize`): each pressure's systolic
(max), diastolic (min), mean ((1/T)∫p dt) and pulse (max − min) pressure,
in dyn/cm² and mmHg; the stroke volume ∫ Q_in dt (the inflow through the
inlet); at each lumen position the distensibility
(A_max − A_min)/(A_min · pulse pressure), A the lumen's section there and the
pulse pressure that of the pressure nearest in z; the pulse-wave velocity
foot to foot between the pressure probes (:func:`multilayer.results.pulse.foot_to_foot`
on the cycle's rows); and each quantity's relative change from the cycle
before, which goes to zero as the run becomes periodic.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from multilayer.plugin.units import MMHG
from multilayer.results.pulse import foot_to_foot
from multilayer.results.reading import without_nan


def windows(t: np.ndarray, period: float, start: float = 0.0) -> list[tuple[int, float, float]]:
    """The complete cycles (k, kT, (k + 1)T) the steps from ``start`` to the rows' times ``t`` cover.

    A cycle's ends are matched to the rows' times to 1e-9 T (steps of a
    decimal Δt do not add up to kT exactly).

    >>> windows(np.arange(1, 26) * 0.1, 1.0)
    [(0, 0.0, 1.0), (1, 1.0, 2.0)]
    >>> windows(np.arange(11, 31) * 0.1, 1.0, start=1.0)
    [(1, 1.0, 2.0), (2, 2.0, 3.0)]
    """
    if not (len(t) and period > 0.0 and math.isfinite(period)):
        return []
    tol = 1e-9 * period
    first = math.ceil((start - tol) / period)
    last = math.floor((float(t[-1]) + tol) / period)  # cycles end at or before the last row
    return [(k, k * period, (k + 1) * period) for k in range(max(first, 0), last)]


def _overlap(t: np.ndarray, a: float, b: float, start: float) -> np.ndarray:
    """|(tᵢ₋₁, tᵢ] ∩ [a, b]| for every row."""
    before = np.concatenate([[start], t[:-1]])
    return np.clip(np.minimum(t, b) - np.maximum(before, a), 0.0, None)


def integral(t: np.ndarray, values: np.ndarray, a: float, b: float, start: float = 0.0) -> np.ndarray:
    """∫ v dt over [a, b]: Σᵢ vᵢ |(tᵢ₋₁, tᵢ] ∩ [a, b]|; ``values`` (rows, ...) gives one integral per column.

    >>> t = np.arange(1, 5) * 0.25
    >>> float(integral(t, np.array([1.0, 2.0, 3.0, 4.0]), 0.0, 0.5)), float(integral(t, np.ones(4), 0.1, 0.6))
    (0.75, 0.5)
    """
    return np.tensordot(_overlap(t, a, b, start), values, axes=(0, 0))


def inside(t: np.ndarray, a: float, b: float, period: float) -> np.ndarray:
    """The rows with a < tᵢ ≤ b (to 1e-9 T)."""
    tol = 1e-9 * period
    return (t > a + tol) & (t <= b + tol)


def pressure_stats(t: np.ndarray, p: np.ndarray, a: float, b: float, start: float = 0.0) -> dict[str, float]:
    """Systolic, diastolic, mean and pulse pressure over the cycle [a, b], in dyn/cm² and mmHg (``_mmHg``).

    >>> t = np.arange(1, 101) * 0.01
    >>> s = pressure_stats(t, 1e5 + 2e4 * np.sin(2 * np.pi * t), 0.0, 1.0)
    >>> round(s["systolic"], 6), round(s["diastolic"], 6), round(s["mean"], 6), round(s["pulse_mmHg"], 4)
    (120000.0, 80000.0, 100000.0, 30.0025)
    """
    rows = inside(t, a, b, b - a)
    stats = {"systolic": float(np.max(p[rows])), "diastolic": float(np.min(p[rows])),
             "mean": float(integral(t, p, a, b, start)) / (b - a)}
    stats["pulse"] = stats["systolic"] - stats["diastolic"]
    return {**stats, **{f"{k}_mmHg": v / MMHG for k, v in stats.items()}}


def nearest(z: float, places: Mapping[str, float]) -> str | None:
    """The name of the place nearest to ``z`` (the first of equals); None when there is none.

    >>> nearest(1.0, {"p_in": 0.0, "p_mid": 3.0}), nearest(2.0, {})
    ('p_in', None)
    """
    return min(places, key=lambda name: abs(places[name] - z), default=None)


def summarize(t: np.ndarray, period: float, pressures: Mapping[str, tuple[float, np.ndarray]],
              inflow: np.ndarray | None = None, areas: Mapping[str, tuple[float, np.ndarray]] | None = None,
              start: float = 0.0, waves: Mapping[str, tuple[float, np.ndarray]] | None = None) -> list[dict]:
    """The summary of every complete cycle of the series, in order.

    Parameters
    ----------
    t : array
        The rows' times (s), increasing; the steps start at ``start``.
    period : float
        T (s).
    pressures : mapping
        name → (z, p per row): each pressure (dyn/cm²) and where along the vessel it is (cm).
    inflow : array, optional
        The flow rate into the vessel through its inlet, per row (cm³/s, or cm²/s per unit depth).
    areas : mapping, optional
        name → (z, A per row): the lumen's section at a position (cm², or cm per unit depth).
    waves : mapping, optional
        name → (z, series per row): the probes whose feet give the pulse-wave velocity (the pressures at
        points along the vessel).

    Returns
    -------
    list of dict
        Per cycle ``index``, ``start``, ``end``; ``pressure`` (name → :func:`pressure_stats` and ``z``);
        ``stroke_volume`` (∫ inflow dt) with an inflow; ``distensibility`` (name → ``z``, ``area_max``,
        ``area_min``, ``pressure`` (the nearest pressure's name), ``pulse_pressure``, ``value`` in cm²/dyn
        and ``per_mmHg``); with ``waves``, ``pulse_wave_velocity`` (:func:`wave_velocity`); from the second cycle on ``change`` (quantity → relative change from the cycle
        before) and ``max_change`` (the largest in size).  A value that cannot be formed is None.
    """
    t = np.asarray(t, dtype=float)
    areas = areas or {}
    out: list[dict] = []
    scales: dict[str, float] = {}
    previous: dict[str, float] = {}
    for k, a, b in windows(t, period, start):
        cycle: dict = {"index": k, "start": a, "end": b, "pressure": {}}
        values: dict[str, float] = {}
        now_scales: dict[str, float] = {}
        for name, (z, p) in pressures.items():
            stats = pressure_stats(t, np.asarray(p, dtype=float), a, b, start)
            cycle["pressure"][name] = {"z": z, **stats}
            for key in ("systolic", "diastolic", "mean", "pulse"):
                values[f"pressure.{name}.{key}"] = stats[key]
                # a pressure that swings about zero is measured against its swing
                now_scales[f"pressure.{name}.{key}"] = max(abs(stats[key]), abs(stats["pulse"]))
        if inflow is not None:
            q = np.asarray(inflow, dtype=float)
            cycle["stroke_volume"] = float(integral(t, q, a, b, start))
            values["stroke_volume"] = cycle["stroke_volume"]
            # the volume moved either way: the scale of a net volume near zero (a flow that reverses)
            now_scales["stroke_volume"] = float(integral(t, np.abs(q), a, b, start))
        places = {name: z for name, (z, _) in pressures.items()}
        if areas:
            cycle["distensibility"] = {}
        for name, (z, area) in areas.items():
            rows = inside(t, a, b, period)
            area = np.asarray(area, dtype=float)[rows]
            high, low = float(np.max(area)), float(np.min(area))
            source = nearest(z, places)
            pulse = cycle["pressure"][source]["pulse"] if source is not None else math.nan
            value = (high - low) / (low * pulse) if pulse > 0.0 and low > 0.0 else math.nan
            cycle["distensibility"][name] = {"z": z, "area_max": high, "area_min": low, "pressure": source,
                                             "pulse_pressure": pulse, "value": value, "per_mmHg": value * MMHG}
            values[f"distensibility.{name}"] = value
            now_scales[f"distensibility.{name}"] = abs(value)
        if waves:
            cycle["pulse_wave_velocity"] = wave_velocity(t, waves, a, b, period)
        if out:
            cycle["change"] = {key: _relative(v, previous.get(key, math.nan), scales.get(key, math.nan))
                               for key, v in values.items()}
            finite = [abs(c) for c in cycle["change"].values() if math.isfinite(c)]
            cycle["max_change"] = max(finite) if finite else math.nan
        previous, scales = values, now_scales
        out.append(without_nan(cycle))
    return out


def wave_velocity(t: np.ndarray, waves: Mapping[str, tuple[float, np.ndarray]], a: float, b: float,
                  period: float) -> dict:
    """The pulse-wave velocity over the cycle [a, b], foot to foot between the ``waves`` (name → (z, series)):
    ``value`` (cm/s) and ``m_s`` (m/s), or None and the ``reason``; ``feet``, each probe's foot time (s, None
    where it has none) and ``z``.

    >>> t = np.arange(1, 2001) * 1e-3
    >>> pulse = lambda z: np.maximum(0.0, np.sin(2 * np.pi * (t - z / 500.0 - 0.1))) ** 2    # c = 5 m/s
    >>> found = wave_velocity(t, {"p_1": (1.0, pulse(1.0)), "p_3": (3.0, pulse(3.0))}, 1.0, 2.0, 1.0)
    >>> feet = [f["time"] for f in found["feet"].values()]
    >>> round(found["m_s"], 6), round(feet[1] - feet[0], 9)      # 2 cm in 4 ms
    (5.0, 0.004)
    """
    rows = inside(t, a, b, period)
    speed, feet = foot_to_foot([(name, z, t[rows], np.asarray(y, dtype=float)[rows]) for name, (z, y) in waves.items()])
    return {"value": speed.value, "m_s": None if speed.value is None else speed.value / 100.0,
            "reason": speed.reason, "feet": {name: {"z": z, "time": feet[name].time} for name, (z, _) in waves.items()}}


def pressure_diameter(t: np.ndarray, pressure: np.ndarray, eta: np.ndarray, radius: float, a: float, b: float,
                      period: float) -> dict:
    """The pressure–diameter loop of a tube over the cycle [a, b] at one place: ``pressure`` (mmHg) and
    ``diameter`` 2(R + η) (mm) on the cycle's rows, and their extremes ``pressure_min``/``_max``,
    ``diameter_min``/``_max``.

    >>> t = np.arange(1, 201) * 0.01
    >>> p = (100 + 20 * np.sin(2 * np.pi * t)) * MMHG
    >>> loop = pressure_diameter(t, p, 0.01 * np.sin(2 * np.pi * t - 0.3), 0.3, 1.0, 2.0, 1.0)
    >>> [round(loop[k], 4) for k in ("pressure_min", "pressure_max", "diameter_min", "diameter_max")]
    [80.0, 120.0, 5.8, 6.2]
    """
    rows = inside(t, a, b, period)
    p = np.asarray(pressure, dtype=float)[rows] / MMHG
    diameter = 20.0 * (radius + np.asarray(eta, dtype=float)[rows])  # cm to mm
    return {"pressure": p, "diameter": diameter, "pressure_min": float(p.min()), "pressure_max": float(p.max()),
            "diameter_min": float(diameter.min()), "diameter_max": float(diameter.max())}


def _relative(now: float, before: float, scale: float) -> float:
    """(now − before)/scale; 0 when both are 0, NaN when it cannot be formed.

    >>> _relative(1.1, 1.0, 1.0), _relative(0.0, 0.0, 0.0), _relative(1.0, 0.0, 0.0)
    (0.10000000000000009, 0.0, nan)
    """
    if not (math.isfinite(now) and math.isfinite(before) and math.isfinite(scale)):
        return math.nan
    if now == before:
        return 0.0
    return (now - before) / scale if scale > 0.0 else math.nan



def last_cycle_line(block: Mapping | None) -> str | None:
    """One line on the last complete cycle of a ``cycles`` block (:func:`summarize` with its period and units), for
    a run's closing lines: each pressure's systolic/diastolic (mean) in mmHg, the stroke volume, and how far the
    cycle is from the one before; None without a complete cycle.

    >>> t = np.arange(1, 201) * 0.01
    >>> p = (100 + 20 * np.sin(2 * np.pi * t)) * MMHG
    >>> block = {"period": 1.0, "units": {"stroke_volume": "mL"},
    ...          "cycles": summarize(t, 1.0, {"p_out": (6.0, p)}, inflow=1 + np.sin(2 * np.pi * t) + t / 20)}
    >>> print(last_cycle_line(block))
    cycle 2 (1–2 s): p_out 120/80 (mean 100) mmHg; stroke volume 1.075 mL; within 4.9 % of cycle 1
    """
    done = (block or {}).get("cycles") or []
    if not done:
        return None
    last = done[-1]
    parts = [f"{name} {p['systolic_mmHg']:.4g}/{p['diastolic_mmHg']:.4g} (mean {p['mean_mmHg']:.4g}) mmHg"
             for name, p in last.get("pressure", {}).items() if "systolic_mmHg" in p and not name.startswith("end.")]
    speed = last.get("pulse_wave_velocity") or {}
    if speed.get("m_s") is not None:
        parts.append(f"pulse-wave velocity {speed['m_s']:.3g} m/s (foot to foot)")
    if "stroke_volume" in last:
        parts.append(f"stroke volume {last['stroke_volume']:.4g} {block.get('units', {}).get('stroke_volume', '')}".rstrip())
    if "max_change" in last:
        parts.append(f"within {100 * last['max_change']:.2g} % of cycle {last['index']}")
    head = f"cycle {last['index'] + 1} ({last['start']:.4g}–{last['end']:.4g} s)"
    return f"{head}: {'; '.join(parts)}" if parts else head
