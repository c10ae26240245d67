"""What compare, study and sweep measure of runs, from their results folders alone."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from multilayer.plugin.registry import Registry
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
    rows), and ``peaked``: False when the peak is on the last row — the pulse
    may still be rising there, so neither time is an arrival yet.

    >>> arrival(np.array([1.0, 2.0, 3.0, 4.0]), np.array([0.0, 1.0, 4.0, -2.0]))
    {'peak': 4.0, 'peak_time': 3.0, 'half_peak_time': 2.3333333333333335, 'peaked': True}
    """
    t, y = finite_rows(t, y)
    a = np.abs(y)
    if not len(a) or a.max() == 0.0:
        return {"peak": None, "peak_time": None, "half_peak_time": None, "peaked": False}
    i_peak = int(np.argmax(a))
    half = 0.5 * a[i_peak]
    i = int(np.argmax(a >= half))
    t_half = t[i] if i == 0 else t[i - 1] + (half - a[i - 1]) / (a[i] - a[i - 1]) * (t[i] - t[i - 1])
    return {"peak": float(a[i_peak]), "peak_time": float(t[i_peak]), "half_peak_time": float(t_half),
            "peaked": i_peak < len(a) - 1}


#: an η probe's peak counts as the pulse's arrival when it is at least this fraction of the largest η probe's peak
ARRIVED = 0.01


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


def lumen_depth(geometry: Mapping[str, Any], registry: Registry) -> float | None:
    """a = A/w(R): the lumen's section A = ∫₀^R w(r) dr per unit of its wall's measure w(R), for the measure
    w = c rᵏ of the case's ``[geometry]`` (resolved): R/(1 + k) — R in the planar channel, R/2 in a tube.

    None when the geometry's plugin cannot be built from the case.
    """
    radius = geometry.get("radius")
    found = registry.find("geometry", geometry.get("kind", "planar"))
    if radius is None or found is None:
        return None
    try:
        shape = found.record.factory(**{k: v for k, v in geometry.items() if k not in ("kind", "length", "radius")})
    except (TypeError, ValueError):
        return None
    return radius / (1 + shape.radial_power)


def long_wave_speeds(case: Mapping[str, Any], registry: Registry) -> dict[str, float | None]:
    """√(a·C0/ρ_f), and √(a·C0/(ρ_f + ρ₁h/a)) with the wall's inertia (theory §9, §11).

    a is :func:`lumen_depth` (R in the planar channel, where these are
    √(R·C0/ρ_f) and √(R·C0/(ρ_f + ρ₁h/R)); R/2 in a tube, Moens–Korteweg's
    √(R·C0/(2ρ_f))).  C0 is the ``long_wave_stiffness(radius=R)`` of the
    first thin layer, built by its plugin's factory from the resolved case.
    None without a fluid, a thin layer, or with C0 = 0 (a wave membrane).
    """
    none = {"long_wave_speed": None, "long_wave_speed_inertia": None}
    fluid, geometry = case.get("fluid"), case.get("geometry") or {}
    radius, depth = geometry.get("radius"), lumen_depth(geometry, registry)
    if not fluid or radius is None or depth is None:
        return none
    for spec in case.get("layers") or []:
        found = registry.find("layer", spec.get("model", ""))
        if found is None or not found.record.thin:
            continue
        try:
            layer = found.record.factory(**{k: v for k, v in spec.items() if k not in ("model", "cells")})
            c0 = float(layer.long_wave_stiffness(radius=radius))
        except (TypeError, ValueError):
            return none
        if c0 <= 0.0:
            return none
        rho = float(fluid["density"])
        surface = getattr(layer, "density", 0.0) * getattr(layer, "thickness", 0.0) / depth
        return {"long_wave_speed": math.sqrt(depth * c0 / rho),
                "long_wave_speed_inertia": math.sqrt(depth * c0 / (rho + surface)) if surface else None}
    return none


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
    # the speed is fitted to the arrivals the series has seen whole, of the pulse itself: a probe it has not
    # reached yet shows only the precursor decaying ahead of it (orders of magnitude smaller), whose peak is no arrival
    lumen = {n: e for n, e in probes.items() if e["quantity"] == "eta" and not e["line"] and e["peak"] is not None}
    largest = max((e["peak"] for e in lumen.values()), default=0.0)
    lumen = {n: e for n, e in lumen.items() if e["peaked"] and e["peak"] >= ARRIVED * largest}
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
        "wave_speed_peak": wave_speed([e["z"] for e in lumen.values()], [e["peak_time"] for e in lumen.values()]),
        "wave_speed_half_peak": wave_speed([e["z"] for e in lumen.values()],
                                           [e["half_peak_time"] for e in lumen.values()]),
        **long_wave_speeds(run.case, registry),
        "peak_pressure": peak_pressure,
        "peak_pressure_probe": peak_pressure_probe,
        "final_energy": float(energy[-1]) if len(energy) else None,
        "max_relative_residual": float(np.nanmax(np.abs(residual))) if len(residual) else None,
    }


def compare_runs(runs: Sequence[RunData], registry: Registry) -> list[dict[str, Any]]:
    """One :func:`measure` per run, the first run the reference of the differences."""
    return [measure(run, runs[0] if i else None, registry) for i, run in enumerate(runs)]
