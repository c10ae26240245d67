"""The results folder of a run: a time series, field snapshots, a summary.

Everything is written so that a run that dies half-way leaves readable
files: ``series.csv`` gets every row as soon as it is appended, and each
``<name>.pvd`` collection is rewritten (atomically) after every snapshot.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np


def _cell(value: Any) -> Any:
    if isinstance(value, float | np.floating):
        return repr(float(value))  # shortest text that reads back to the same double
    return value


class SeriesWriter:
    """Appends rows to a CSV file, header first, each row on disk before ``append`` returns."""

    def __init__(self, path: Path, columns: Sequence[str]):
        self.path = path
        self.columns = list(columns)
        self._known = frozenset(self.columns)
        with open(self.path, "w", newline="") as f:
            csv.writer(f).writerow(self.columns)

    def append(self, row: Mapping[str, Any]) -> None:
        """Write one row; a column the row lacks is left empty, an unknown key is an error."""
        unknown = row.keys() - self._known
        if unknown:
            raise KeyError(f"not columns of {self.path.name}: {sorted(unknown)}")
        with open(self.path, "a", newline="") as f:
            csv.writer(f).writerow([_cell(row.get(c, "")) for c in self.columns])


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, set | frozenset | tuple):
        return list(value)
    raise TypeError(f"{type(value).__name__} is not JSON serializable")


def _write_atomically(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


class ResultsFolder:
    """The output folder of one run.

    Examples
    --------
    >>> import tempfile
    >>> out = ResultsFolder(Path(tempfile.mkdtemp()) / "run")
    >>> series = out.series(["step", "t"])
    >>> series.append({"step": 1, "t": 1e-4})
    >>> (out.path / "series.csv").read_text().splitlines()
    ['step,t', '1,0.0001']
    """

    #: the parts a run writes snapshots of
    PARTS = ("wall", "fluid")

    def __init__(self, out: Path | str):
        self.path = Path(out)
        if self.path.exists() and not self.path.is_dir():
            raise NotADirectoryError(f"--out {self.path} is a file, not a folder")
        self.path.mkdir(parents=True, exist_ok=True)
        self._clear_previous_run()
        self._snapshots: dict[str, list[tuple[float, str]]] = {}

    def _clear_previous_run(self) -> None:
        """Remove what an earlier run wrote here, so no stale row or snapshot survives this one."""
        stale = [self.path / "series.csv", self.path / "summary.json"]
        for part in self.PARTS:
            stale += [self.path / f"{part}.pvd", *self.path.glob(f"{part}_[0-9][0-9][0-9][0-9][0-9][0-9].vtu")]
        for path in stale:
            path.unlink(missing_ok=True)

    def series(self, columns: Sequence[str], name: str = "series.csv") -> SeriesWriter:
        """A writer of ``series.csv`` with these columns."""
        return SeriesWriter(self.path / name, columns)

    def snapshot(
        self,
        name: str,
        points: np.ndarray,
        cells: Mapping[str, np.ndarray],
        point_data: Mapping[str, np.ndarray] | None = None,
        t: float = 0.0,
        step: int = 0,
    ) -> Path:
        """Write ``<name>_<step:06d>.vtu`` and list it in ``<name>.pvd`` at time ``t``.

        ``points`` are (z, r) or (z, r, 0) rows; a 2-column point field is
        padded with zeros so that ParaView reads it as a vector.
        """
        points = np.asarray(points, dtype=float)
        if points.shape[1] == 2:
            points = np.column_stack([points, np.zeros(len(points))])
        data = {}
        for key, values in (point_data or {}).items():
            values = np.asarray(values, dtype=float)
            if values.ndim == 2 and values.shape[1] == 2:
                values = np.column_stack([values, np.zeros(len(values))])
            data[key] = values
        file = f"{name}_{step:06d}.vtu"
        meshio.write(self.path / file, meshio.Mesh(points, dict(cells), point_data=data))
        entries = self._snapshots.setdefault(name, [])
        entries.append((float(t), file))
        _write_atomically(self.path / f"{name}.pvd", _pvd(entries))
        return self.path / file

    def write_json(self, name: str, data: Mapping[str, Any]) -> Path:
        """Write ``name`` as indented JSON (numpy scalars and arrays converted)."""
        path = self.path / name
        _write_atomically(path, json.dumps(data, indent=2, default=_jsonable, allow_nan=True) + "\n")
        return path

    def write_summary(self, summary: Mapping[str, Any]) -> Path:
        """Write ``summary.json``."""
        return self.write_json("summary.json", summary)


def _pvd(entries: Sequence[tuple[float, str]]) -> str:
    """A ParaView collection of ``(t, file)`` snapshots."""
    lines = [
        '<?xml version="1.0"?>',
        '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
        "  <Collection>",
    ]
    for t, file in entries:
        stamp = "%.17g" % t if math.isfinite(t) else "0"
        lines.append(f'    <DataSet timestep="{stamp}" group="" part="0" file={quoteattr(file)}/>')
    lines += ["  </Collection>", "</VTKFile>", ""]
    return "\n".join(lines)
