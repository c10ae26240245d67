"""What ``multilayer compare`` measures, read from results folders alone.

Every number comes from a run's own ``summary.json``, ``series.csv`` and wall
snapshots, so it can be recomputed from those files.
"""

from __future__ import annotations

import csv
import json
import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs
import meshio
import numpy as np

from multilayer.registry import Registry




@attrs.frozen(eq=False)
class RunData:
    """What a results folder holds, read back."""

    label: str
    folder: Path
    summary: Mapping[str, Any]
    series: Mapping[str, np.ndarray]  #: column → values, one per step (NaN where empty)

    @property
    def case(self) -> Mapping[str, Any]:
        """The resolved case of ``summary.json`` ({} if there is none)."""
        return self.summary.get("case") or {}

    @property
    def probes(self) -> list[Mapping[str, Any]]:
        """The probes of the resolved case that have a column in ``series.csv``."""
        return [p for p in (self.case.get("output") or {}).get("probes", []) if p["name"] in self.series]

    @property
    def t(self) -> np.ndarray:
        return self.series.get("t", np.zeros(0))


def read_series(path: Path) -> dict[str, np.ndarray]:
    """``series.csv`` as column → float array; {} when the file is missing."""
    if not path.is_file():
        return {}
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        return {}
    columns, body = rows[0], rows[1:]
    return {c: np.array([float(r[i]) if i < len(r) and r[i] != "" else math.nan for r in body])
            for i, c in enumerate(columns)}


def read_run(label: str, folder: Path, status: str | None = None, reason: str = "") -> RunData:
    """The summary and series of the results folder ``folder`` (empty parts when missing).

    ``status`` and ``reason``, when given, are what running it returned;
    they replace the summary's when the two disagree (a run that raised
    before its ``summary.json`` said so).
    """
    summary_path = folder / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.is_file() else {}
    if status is not None and summary.get("status") != status:
        summary = {**summary, "status": status, "reason": reason}
    return RunData(label, folder, summary, read_series(folder / "series.csv"))


def dof_counts(summary: Mapping[str, Any]) -> dict[str, int]:
    """The DOFs of ``summary.json`` by part, ``wall_free`` left out (it is part of ``wall``).

    >>> dof_counts({"dofs": {"wall": 7, "wall_free": 5, "fluid": 9}})
    {'wall': 7, 'fluid': 9}
    """
    return {k: v for k, v in (summary.get("dofs") or {}).items() if k != "wall_free"}


def without_nan(value: Any) -> Any:
    """JSON has no NaN: a non-finite number becomes null (in nested tables and lists too).

    >>> without_nan({"a": [1.0, float("nan")], "b": float("inf")})
    {'a': [1.0, None], 'b': None}
    """
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Mapping):
        return {k: without_nan(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [without_nan(v) for v in value]
    return value


def lumen_eta(folder: Path, radius: float, part: str = "wall") -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """η(z, t) on the lumen line: from ``eta_lumen.csv`` (every step), else the ``<part>_*.vtu`` snapshots.

    Returns (z, t, eta) with ``eta[i, j]`` = η(t[i], z[j]): the radial
    displacement of the lumen's vertices (reference coordinates), sorted by
    z.  None when the run wrote neither.
    """
    table = folder / "eta_lumen.csv"
    if table.is_file():
        series = read_series(table)
        columns = [c for c in series if c.startswith("z=")]
        if columns and len(series["t"]):
            z = np.array([float(c[2:]) for c in columns])
            order = np.argsort(z, kind="stable")
            eta = np.column_stack([series[c] for c in columns])[:, order]
            return z[order], series["t"], eta
    pvd = folder / f"{part}.pvd"
    if not pvd.is_file():
        return None
    times, rows, z = [], [], None
    for dataset in ET.parse(pvd).getroot().iter("DataSet"):
        mesh = meshio.read(folder / dataset.get("file"))
        on_lumen = np.isclose(mesh.points[:, 1], radius, rtol=0.0, atol=1e-9 * radius)
        order = np.argsort(mesh.points[on_lumen, 0], kind="stable")
        z = mesh.points[on_lumen, 0][order]
        rows.append(mesh.point_data["displacement"][on_lumen, 1][order])
        times.append(float(dataset.get("timestep")))
    if not rows:
        return None
    return z, np.array(times), np.array(rows)




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


def finite_rows(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t, y) without the rows where either is NaN or infinite (an empty CSV cell reads as NaN)."""
    keep = np.isfinite(t) & np.isfinite(y)
    return np.asarray(t)[keep], np.asarray(y)[keep]


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


def long_wave_speeds(case: Mapping[str, Any], registry: Registry) -> dict[str, float | None]:
    """√(R·C0/ρ_f), and √(R·C0/(ρ_f + ρ₁h/R)) with the wall's inertia (theory §9).

    C0 is the ``long_wave_stiffness(radius=R)`` of the first thin layer,
    built by its plugin's factory from the resolved case.  None without a
    fluid, a thin layer, or with C0 = 0 (a wave membrane).
    """
    none = {"long_wave_speed": None, "long_wave_speed_inertia": None}
    fluid, radius = case.get("fluid"), (case.get("geometry") or {}).get("radius")
    if not fluid or radius is None:
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
        surface = getattr(layer, "density", 0.0) * getattr(layer, "thickness", 0.0) / radius
        return {"long_wave_speed": math.sqrt(radius * c0 / rho),
                "long_wave_speed_inertia": math.sqrt(radius * c0 / (rho + surface)) if surface else None}
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
    # the speed is fitted to the arrivals the series has seen whole
    lumen = {n: e for n, e in probes.items() if e["quantity"] == "eta" and not e["line"] and e["peaked"]}
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
