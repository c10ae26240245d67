"""What compare, study and sweep measure of runs, from their results folders alone.

The pulse-wave velocities (foot to foot, the ΔP–ΔA loop) and the stack's long-wave speed are
:mod:`multilayer.campaign.pulse_wave`'s; every speed comes with the reason when there is none.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from multilayer.campaign.pulse_wave import radial_power, stack_long_wave_speed
from multilayer.plugin.registry import Registry
from multilayer.plugin.units import MMHG
from multilayer.results.pulse import ARRIVED, Speed, foot_to_foot, loop_speed
from multilayer.results.reading import RunData, dof_counts, finite_rows


def max_abs_difference(t_a: np.ndarray, y_a: np.ndarray, t_b: np.ndarray, y_b: np.ndarray) -> float | None:
    """max |y_a − y_b| of the two piecewise-linear series over their common time span.

    Both are evaluated on the union of their times inside the span, which
    holds every kink of either, so this is the exact maximum of the
    difference of the linear interpolants (and the plain max |Δ| on a
    shared time grid).  None when the spans do not overlap.

    >>> t = np.array([0.0, 1.0, 2.0])
    >>> max_abs_difference(t, np.array([0.0, 1.0, 0.0]), np.array([0.0, 2.0]), np.array([0.0, 0.0]))
    1.0
    """
    a, b = finite_rows(t_a, y_a), finite_rows(t_b, y_b)
    if not len(a[0]) or not len(b[0]):
        return None
    lo, hi = max(a[0][0], b[0][0]), min(a[0][-1], b[0][-1])
    if lo > hi:
        return None
    grid = np.union1d(a[0], b[0])
    grid = grid[(grid >= lo) & (grid <= hi)]
    return float(np.max(np.abs(np.interp(grid, *a) - np.interp(grid, *b))))


def arrival(t: np.ndarray, y: np.ndarray) -> dict[str, Any]:
    """The pulse at a probe: ``peak`` max |y|, ``peak_time`` its (first) time,
    ``half_peak_time`` the first time |y| reaches half the peak (linear between
    rows), ``peaked``: False when the peak is on the last row — the pulse
    may still be rising there, so neither time is an arrival yet — and
    ``displaced``: True when the first row already holds half the peak (a wall
    started deflected, ``initial.pressure``): then neither time is an arrival.

    >>> arrival(np.array([1.0, 2.0, 3.0, 4.0]), np.array([0.0, 1.0, 4.0, -2.0]))
    {'peak': 4.0, 'peak_time': 3.0, 'half_peak_time': 2.3333333333333335, 'peaked': True, 'displaced': False}
    """
    t, y = finite_rows(t, y)
    a = np.abs(y)
    if not len(a) or a.max() == 0.0:
        return {"peak": None, "peak_time": None, "half_peak_time": None, "peaked": False, "displaced": False}
    i_peak = int(np.argmax(a))
    half = 0.5 * a[i_peak]
    i = int(np.argmax(a >= half))
    t_half = t[i] if i == 0 else t[i - 1] + (half - a[i - 1]) / (a[i] - a[i - 1]) * (t[i] - t[i - 1])
    return {"peak": float(a[i_peak]), "peak_time": float(t[i_peak]), "half_peak_time": float(t_half),
            "peaked": i_peak < len(a) - 1, "displaced": bool(i == 0)}


def wave_speed(z: Sequence[float], times: Sequence[float | None]) -> float | None:
    """Least-squares slope of z against arrival time (cm/s); None below two distinct times.

    >>> wave_speed([1.0, 2.0, 4.0], [0.001, 0.002, 0.004])
    1000.0
    """
    pairs = [(zi, ti) for zi, ti in zip(z, times) if ti is not None]
    if len(pairs) < 2:
        return None
    zs, ts = np.array(pairs, dtype=float).T
    dt = ts - ts.mean()
    if not np.any(dt):
        return None
    return float(np.sum(dt * (zs - zs.mean())) / np.sum(dt * dt))


def arrival_speed(lumen: Mapping[str, Mapping[str, Any]], key: str) -> Speed:
    """:func:`wave_speed` of the ``key`` times (``peak_time``, ``half_peak_time``) of the lumen's η probes
    (their :func:`arrival` entries, by name), or why there is none.

    A probe whose peak is on the last row, below :data:`~multilayer.campaign.pulse_wave.ARRIVED` of the largest
    peak, or whose first row already holds half its peak, has seen no arrival and is left out.

    >>> entry = lambda z, t: {"z": z, "peak": 1.0, "peak_time": t, "peaked": True, "displaced": False}
    >>> arrival_speed({"a": entry(1.0, 0.002), "b": entry(2.0, 0.004)}, "peak_time").cell()
    '500'
    >>> arrival_speed({"a": entry(1.0, 0.004), "b": entry(2.0, 0.002)}, "peak_time").reason
    'the arrivals do not come later downstream (a wave running upstream, or a wall started deflected)'
    """
    largest = max((e["peak"] for e in lumen.values() if e["peak"] is not None), default=0.0)
    used, left = [], []
    for name, e in lumen.items():
        why = ("no pulse" if e["peak"] is None else "its peak is on the last row" if not e["peaked"]
               else "not arrived: its peak is under 1 % of the largest" if e["peak"] < ARRIVED * largest
               else "its first row already holds half its peak" if e["displaced"] else "")
        if why:
            left.append(f"{name}: {why}")
        else:
            used.append(e)
    times = {e[key] for e in used}
    if len(used) < 2:
        return Speed(None, "fewer than two arrivals" + (f" ({'; '.join(left)})" if left else ""))
    if len(times) < 2 or len({e["z"] for e in used}) < 2:
        return Speed(None, "every arrival at the same time or place")
    speed = wave_speed([e["z"] for e in used], [e[key] for e in used])
    if speed is None or not speed > 0.0:
        return Speed(None, "the arrivals do not come later downstream (a wave running upstream, or a wall started "
                           "deflected)")
    return Speed(speed)


def loop_speeds(run: RunData, probes: Mapping[str, Mapping[str, Any]], registry: Registry) -> list[dict[str, Any]]:
    """:func:`~multilayer.campaign.pulse_wave.loop_speed` at every place with a ``p`` probe and an ``eta`` probe
    on the lumen (the first of each at that z): ``z``, the two probes' names, ``value`` and ``reason``.

    ``probes`` are the column's probe entries with their feet (``foot_time``, ``foot_reason``): where either
    probe has none (the pulse has not arrived, or has not passed) there is no loop either."""
    geometry, fluid = run.case.get("geometry") or {}, run.case.get("fluid")
    power = radial_power(geometry, registry)
    out = []
    for name, e in probes.items():
        if e["quantity"] != "p":
            continue
        eta = next((n for n, q in probes.items() if q["quantity"] == "eta" and not q["line"] and q["z"] == e["z"]),
                   None)
        if eta is None or any(o["z"] == e["z"] for o in out):
            continue
        unseen = next((f"no {what} foot: {probes[n]['foot_reason']}" for n, what in ((name, "pressure"), (eta, "η"))
                       if probes[n].get("foot_time") is None), None)
        if not fluid or power is None or geometry.get("radius") is None:
            speed = Speed(None, "no fluid" if not fluid else "the geometry is unknown here")
        elif unseen:  # (the feet of foot_to_foot: a probe the pulse has not reached has none)
            speed = Speed(None, unseen)
        else:
            speed = loop_speed(run.t, run.series[name], run.series[eta], geometry["radius"], power,
                               float(fluid["density"]))
        out.append({"z": e["z"], "pressure": name, "eta": eta, "value": speed.value, "reason": speed.reason})
    return out


def measure(run: RunData, reference: RunData | None, registry: Registry) -> dict[str, Any]:
    """Every number of one report column, from the run's own files.

    Differences are against ``reference`` (None for the reference itself),
    at the ``eta`` probes both runs have (same name).
    """
    s, series = run.summary, run.series
    dofs = dof_counts(s)
    probes = {}
    for p in run.probes:
        entry = {"quantity": p["quantity"], "z": p["z"], "r": p.get("r"), "line": p.get("line")}
        if p["quantity"] == "eta":
            entry.update(arrival(run.t, series[p["name"]]))
            if reference is not None:
                other = next((q for q in reference.probes if q["name"] == p["name"] and q["quantity"] == "eta"), None)
                entry["max_abs_diff"] = None if other is None else max_abs_difference(
                    run.t, series[p["name"]], reference.t, reference.series[p["name"]])
        probes[p["name"]] = entry
    # the speeds are fitted to the arrivals the series has seen whole, of the pulse itself: a probe it has not
    # reached yet shows only the precursor decaying ahead of it (orders of magnitude smaller), whose peak is no arrival
    lumen = {n: e for n, e in probes.items() if e["quantity"] == "eta" and not e["line"]}
    speeds = {}
    for key, quantity in (("pwv_foot_eta", "eta"), ("pwv_foot_p", "p")):
        chosen = lumen if quantity == "eta" else {n: e for n, e in probes.items() if e["quantity"] == "p"}
        speed, feet = foot_to_foot([(n, e["z"], run.t, series[n]) for n, e in chosen.items()])
        speeds.update(speed.items(key))
        for n, f in feet.items():
            probes[n].update(foot_time=f.time, foot_reason=f.reason)
    pressures = [(float(np.nanmax(series[n])), n) for n, e in probes.items()
                 if e["quantity"] == "p" and np.isfinite(series[n]).any()]
    peak_pressure, peak_pressure_probe = max(pressures) if pressures else (None, None)
    energy = series.get("energy.total", np.zeros(0))
    residual = series.get("energy.relative_residual", np.zeros(0))
    return {
        "label": run.label,
        "out": run.folder.name,
        "status": s.get("status", "failed"),
        "reason": s.get("reason", "" if s else "no summary.json written"),
        "dofs": dofs,
        "dofs_total": sum(dofs.values()) if dofs else None,
        "steps": s.get("steps"),
        "wall_time_s": s.get("wall_time_s"),
        "probes": probes,
        **speeds,
        "pwv_loop": loop_speeds(run, probes, registry),
        **arrival_speed(lumen, "peak_time").items("wave_speed_peak"),
        **arrival_speed(lumen, "half_peak_time").items("wave_speed_half_peak"),
        **stack_long_wave_speed(run.case, registry).items("long_wave_speed"),
        "peak_pressure": peak_pressure,
        "peak_pressure_mmHg": None if peak_pressure is None else peak_pressure / MMHG,
        "peak_pressure_probe": peak_pressure_probe,
        "final_energy": float(energy[-1]) if len(energy) else None,
        "energy_unit": (s.get("units") or {}).get("energy", "erg/cm"),
        "max_relative_residual": float(np.nanmax(np.abs(residual))) if len(residual) else None,
    }


def compare_runs(runs: Sequence[RunData], registry: Registry) -> list[dict[str, Any]]:
    """One :func:`measure` per run, the first run the reference of the differences."""
    return [measure(run, runs[0] if i else None, registry) for i, run in enumerate(runs)]
