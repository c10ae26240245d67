"""A results folder read back: its summary, series and wall snapshots as arrays.

A folder is data users copy, share and download, and a run may still be
writing it (or have been killed while it did): every reader here bounds the
size it reads (:data:`MAX_SUMMARY`, :data:`MAX_TABLE`, :data:`MAX_SNAPSHOT`),
reads a table's last line only when it is whole, and turns whatever it
cannot read (not JSON, not numbers, not a VTU) into one
:class:`~multilayer.results.files.ResultsError` naming the file.
"""

from __future__ import annotations

import contextlib
import csv
import io
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

#: the largest ``summary.json`` read (the resolved case and the run's figures: kilobytes)
MAX_SUMMARY = 64 * 2**20
#: the largest table read (``series.csv``, ``eta_lumen.csv``: a long adaptive run writes tens of MB)
MAX_TABLE = 2**30
#: the largest snapshot read
MAX_SNAPSHOT = 2**30


def _size_checked(path: Path, limit: int, what: str) -> Path:
    """``path`` when it is at most ``limit`` bytes; ResultsError otherwise."""
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise ResultsError(f"{path} cannot be read: {exc.strerror or exc}") from None
    if size > limit:
        raise ResultsError(f"{path} is {size:,} bytes, more than {what} of a run ever is ({limit:,}): not read")
    return path


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
        case = self.summary.get("case")
        return case if isinstance(case, Mapping) else {}

    @property
    def probes(self) -> list[Mapping[str, Any]]:
        """The probes of the resolved case that have a column in ``series.csv``."""
        return [p for p in (self.case.get("output") or {}).get("probes", []) if p["name"] in self.series]

    @property
    def t(self) -> np.ndarray:
        return self.series.get("t", np.zeros(0))


def read_series(path: Path) -> dict[str, np.ndarray]:
    """A table a run writes (``series.csv``, ``eta_lumen.csv``) as column → float array; {} when it is missing.

    An empty cell reads as NaN.  A last line without its newline is a row the
    run was writing when it stopped (or is writing now): it is left out.

    Raises
    ------
    ResultsError
        The file is larger than :data:`MAX_TABLE`, not text, or holds a cell that is not a number.
    """
    if not path.is_file():
        return {}
    try:
        text = _size_checked(path, MAX_TABLE, "a table").read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ResultsError(f"{path} is not a table of a run (not text: {exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise ResultsError(f"{path} cannot be read: {exc.strerror or exc}") from None
    lines = text.split("\n")
    whole = lines[:-1]  # the part after the last newline is a row still being written, or nothing
    rows = list(csv.reader(whole))
    if not rows:
        return {}
    columns, body = rows[0], rows[1:]
    values = np.full((len(body), len(columns)), math.nan)
    for k, row in enumerate(body):
        for i, cell in enumerate(row[:len(columns)]):
            if cell != "":
                try:
                    values[k, i] = float(cell)
                except ValueError:
                    raise ResultsError(f"{path}, line {k + 2}, column {columns[i]!r}: {cell[:40]!r} is not a "
                                       f"number: not a table of a run") from None
    return {c: values[:, i].copy() for i, c in enumerate(columns)}


def read_summary(path: Path) -> dict[str, Any]:
    """``summary.json`` as a mapping; {} when it is missing.

    Raises
    ------
    ResultsError
        The file is larger than :data:`MAX_SUMMARY`, not JSON, nested beyond reason, or not a mapping.
    """
    if not path.is_file():
        return {}
    try:
        summary = json.loads(_size_checked(path, MAX_SUMMARY, "a summary").read_bytes())
    except (OSError, ValueError) as exc:
        raise ResultsError(f"{path} cannot be read (not JSON: {exc})") from None
    except RecursionError:
        raise ResultsError(f"{path} is nested deeper than a summary ever is: not read") from None
    if not isinstance(summary, dict):
        raise ResultsError(f"{path} is not a summary of a run (a JSON {type(summary).__name__}, not an object)")
    for key, kinds in _SUMMARY_KINDS.items():
        if key in summary and summary[key] is not None and not isinstance(summary[key], kinds):
            raise ResultsError(f"{path}: {key} is a JSON {type(summary[key]).__name__}, which a run never writes "
                               f"there: not a summary of a run")
    return summary


#: what the entries of ``summary.json`` that readers use are, when present
_SUMMARY_KINDS: dict[str, type | tuple[type, ...]] = {
    "status": str, "reason": str, "steps": int, "case": dict, "energy": dict, "volume": dict, "dofs": dict}


def read_run(label: str, folder: Path, status: str | None = None, reason: str = "") -> RunData:
    """The summary and series of the results folder ``folder`` (empty parts when missing).

    ``status`` and ``reason``, when given, are what running it returned;
    they replace the summary's when the two disagree (a run that raised
    before its ``summary.json`` said so).

    Raises
    ------
    ResultsError
        A file of the folder cannot be read (:func:`read_summary`, :func:`read_series`).
    """
    summary = read_summary(folder / "summary.json")
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


def position_column(z: float) -> str:
    """The column of a lumen table (``eta_lumen.csv``, ``wss_lumen.csv``) at the position ``z`` (cm): ``z=<z>``,
    z rounded to 12 significant digits and written in its shortest form (no float noise of a mesh's arithmetic).

    >>> position_column(0.6000000000000001), position_column(3.0), position_column(1e-05), position_column(0.1 + 0.2)
    ('z=0.6', 'z=3.0', 'z=1e-05', 'z=0.3')
    """
    return f"z={float(f'{float(z):.12g}')!r}"


def lumen_table(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """A lumen table (``eta_lumen.csv``, ``wss_lumen.csv``: ``step``, ``t``, then one ``z=<position>`` column per
    lumen vertex) as :func:`lumen_field` of its columns; None when it is missing or has no rows.

    Raises
    ------
    ResultsError
        The file cannot be read as a table (:func:`read_series`), or a column is not ``z=<position>``.
    """
    return lumen_field(read_series(path), path)


def lumen_field(table: Mapping[str, np.ndarray], where: Path | str = "the table"
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(z, t, values) of a lumen table's columns, ``values[i, j]`` at (t[i], z[j]), sorted by z; None without rows.

    >>> z, t, v = lumen_field({"step": np.array([1.0]), "t": np.array([0.1]), "z=1.0": np.array([5.0]),
    ...                        "z=0.5": np.array([4.0])})
    >>> z.tolist(), t.tolist(), v.tolist()
    ([0.5, 1.0], [0.1], [[4.0, 5.0]])
    """
    columns = [c for c in table if c.startswith("z=")]
    if not (columns and len(table["t"])):
        return None
    positions = []
    for column in columns:
        try:
            positions.append(float(column[2:]))
        except ValueError:
            raise ResultsError(f"{where} has a column {column!r}, not z=<position>: not a table of a run") from None
    z = np.array(positions)
    order = np.argsort(z, kind="stable")
    return z[order], table["t"], np.column_stack([table[c] for c in columns])[:, order]


def lumen_wss(folder: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """τ_w(z, t) on the lumen from ``wss_lumen.csv``: (z, t, wss) as :func:`lumen_table`; None without it."""
    return lumen_table(folder / "wss_lumen.csv")


def lumen_eta(folder: Path, radius: float, part: str = "wall") -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """η(z, t) on the lumen line: from ``eta_lumen.csv`` (every step), else the ``<part>_*.vtu`` snapshots.

    Returns (z, t, eta) with ``eta[i, j]`` = η(t[i], z[j]): the radial
    displacement of the lumen's vertices (reference coordinates), sorted by
    z.  None when the run wrote neither.
    """
    table = folder / "eta_lumen.csv"
    if table.is_file() and (field := lumen_table(table)) is not None:
        return field
    pvd = folder / f"{part}.pvd"
    if not pvd.is_file():
        return None
    try:
        datasets = list(ET.parse(_size_checked(pvd, MAX_SUMMARY, "a collection")).getroot().iter("DataSet"))
    except (OSError, ET.ParseError) as exc:
        raise ResultsError(f"{pvd} cannot be read (not a collection of snapshots: {exc})") from None
    times, rows, z = [], [], None
    for dataset in datasets:
        name = dataset.get("file")
        # a collection is data: it may name only this part's snapshots, directly inside the folder
        if not ((snapshot := snapshot_of(name)) and snapshot[0] == part and not (folder / name).is_symlink()):
            raise ResultsError(f"{pvd} names {name!r}, not a snapshot {part}_<step>.vtu of the run in its folder: "
                               "not read")
        try:
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
                mesh = meshio.read(_size_checked(folder / name, MAX_SNAPSHOT, "a snapshot"))
            on_lumen = np.isclose(mesh.points[:, 1], radius, rtol=0.0, atol=1e-9 * radius)
            order = np.argsort(mesh.points[on_lumen, 0], kind="stable")
            z = mesh.points[on_lumen, 0][order]
            rows.append(mesh.point_data["displacement"][on_lumen, 1][order])
            times.append(float(dataset.get("timestep")))
        except ResultsError:
            raise
        except (Exception, SystemExit) as exc:  # meshio's parsers raise what they raise, and its VTU reader exits
            why = "not a VTU file meshio parses" if isinstance(exc, SystemExit) else \
                f"{type(exc).__name__}: {str(exc)[:120]}"
            raise ResultsError(f"{folder / name} cannot be read as a snapshot of the run ({why})") from None
    if not rows:
        return None
    return z, np.array(times), np.array(rows)


def finite_rows(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t, y) without the rows where either is NaN or infinite (an empty CSV cell reads as NaN)."""
    keep = np.isfinite(t) & np.isfinite(y)
    return np.asarray(t)[keep], np.asarray(y)[keep]
