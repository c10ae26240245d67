"""A results folder read back: its summary, series and wall snapshots as arrays."""

from __future__ import annotations

import csv
import json
import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import attrs
import meshio
import numpy as np

from multilayer.results.files import ResultsError
from multilayer.results.folder import snapshot_of


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
        name = dataset.get("file")
        # a collection is data: it may name only this part's snapshots, directly inside the folder
        if not ((snapshot := snapshot_of(name)) and snapshot[0] == part and not (folder / name).is_symlink()):
            raise ResultsError(f"{pvd} names {name!r}, not a snapshot {part}_<step>.vtu of the run in its folder: "
                               "not read")
        mesh = meshio.read(folder / name)
        on_lumen = np.isclose(mesh.points[:, 1], radius, rtol=0.0, atol=1e-9 * radius)
        order = np.argsort(mesh.points[on_lumen, 0], kind="stable")
        z = mesh.points[on_lumen, 0][order]
        rows.append(mesh.point_data["displacement"][on_lumen, 1][order])
        times.append(float(dataset.get("timestep")))
    if not rows:
        return None
    return z, np.array(times), np.array(rows)


def finite_rows(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t, y) without the rows where either is NaN or infinite (an empty CSV cell reads as NaN)."""
    keep = np.isfinite(t) & np.isfinite(y)
    return np.asarray(t)[keep], np.asarray(y)[keep]
