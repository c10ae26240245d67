"""A results folder held in memory: what a run writes, kept as rows and a summary instead of files.

:class:`HeldResults` stands in for :class:`~multilayer.results.folder.ResultsFolder`
in the run loop (:func:`multilayer.runner.loop.run_held`), so a run without a
folder goes through the same loop, writes the same rows and the same summary,
and touches no disk.  Snapshots are not kept (a run's fields are the
:class:`~multilayer.scene.state.State` values of
:func:`~multilayer.runner.stepping.iterate_steps`); nor are checkpoints.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from multilayer.results.folder import _jsonable


class HeldSeries:
    """The rows of one table (``series.csv``, ``eta_lumen.csv``), as :class:`SeriesWriter` would write them.

    >>> table = HeldSeries(["step", "t", "x"])
    >>> table.append({"step": 1, "t": 0.5})
    >>> table.arrays()
    {'step': array([1.]), 't': array([0.5]), 'x': array([nan])}
    """

    def __init__(self, columns: Sequence[str]):
        self.columns = list(columns)
        self._known = frozenset(self.columns)
        self.rows: list[dict[str, Any]] = []

    def append(self, row: Mapping[str, Any]) -> None:
        """Keep one row; a column the row lacks stays empty (NaN), an unknown key is an error."""
        unknown = row.keys() - self._known
        if unknown:
            raise KeyError(f"not columns of the table: {sorted(unknown)}")
        self.rows.append(dict(row))

    def undo(self) -> None:
        """Drop the last row (its partner table could not take its row)."""
        if self.rows:
            self.rows.pop()

    def arrays(self) -> dict[str, np.ndarray]:
        """Column → float array, as :func:`multilayer.results.reading.read_series` reads the file back."""
        return {c: np.array([float(r[c]) if r.get(c, "") != "" else math.nan for r in self.rows], dtype=float)
                for c in self.columns}


class HeldResults:
    """The tables and the summary of a run without a results folder (``path`` is None)."""

    path = None

    def __init__(self) -> None:
        self.tables: dict[str, HeldSeries] = {}
        self.summary: dict[str, Any] = {}

    @property
    def snapshots(self) -> dict[str, list[tuple[float, str]]]:
        return {}

    def series(self, columns: Sequence[str], name: str = "series.csv", keep_until: int | None = None) -> HeldSeries:
        """A new table ``name`` with these columns (it replaces one of the same name)."""
        self.tables[name] = HeldSeries(columns)
        return self.tables[name]

    def snapshot(self, name: str, points: np.ndarray, cells: Mapping[str, np.ndarray],
                 point_data: Mapping[str, np.ndarray] | None = None, t: float = 0.0, step: int = 0) -> Path | None:
        """Snapshots are not held."""
        return None

    def write_summary(self, summary: Mapping[str, Any]) -> None:
        """Keep the summary as ``summary.json`` would read back (plain JSON data, NaN kept)."""
        self.summary = json.loads(json.dumps(summary, default=_jsonable, allow_nan=True))

    def release(self) -> None:
        """Nothing to give up."""
