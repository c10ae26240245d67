"""The results folder of a run: a time series, field snapshots, a summary.

Everything is written so that a run that dies half-way leaves readable
files: ``series.csv`` gets every row as soon as it is appended, each
``<name>.pvd`` collection is valid after every snapshot (a new entry
overwrites only the closing tags, so a snapshot costs the same however many
came before), and ``summary.json`` has its room reserved on disk when the
run starts, so it is written even when the disk fills up.

A folder is held by one run at a time (``.lock`` with the run's PID) and is
checked to be writable before any work starts.
"""

from __future__ import annotations

import csv
import errno
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


class ResultsError(Exception):
    """The results folder cannot be used (not writable, held by another run); the message says why."""


class SeriesWriter:
    """Appends rows to a CSV file, header first, each row on disk before ``append`` returns.

    With ``keep_until`` (a resumed run) the file is kept, cut after the last row
    whose ``step`` is ≤ ``keep_until``, and must have the same columns.
    """

    def __init__(self, path: Path, columns: Sequence[str], keep_until: int | None = None):
        self.path = path
        self.columns = list(columns)
        self._known = frozenset(self.columns)
        if keep_until is not None and path.is_file():
            self._cut(keep_until)
            return
        with open(self.path, "w", newline="") as f:
            csv.writer(f).writerow(self.columns)

    def _cut(self, step: int) -> None:
        with open(self.path, newline="") as f:
            rows = list(csv.reader(f))
        if not rows or rows[0] != self.columns:
            raise ResultsError(f"{self.path} does not have the columns of this run: cannot resume into it")
        kept = [r for r in rows[1:] if r and int(float(r[0])) <= step]
        with open(self.path, "w", newline="") as f:
            csv.writer(f).writerows([rows[0], *kept])

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
    #: bytes kept on disk for summary.json from the start of a run
    RESERVE = 1 << 16

    def __init__(self, out: Path | str, fresh: bool = True):
        self.path = Path(out)
        if self.path.exists() and not self.path.is_dir():
            raise NotADirectoryError(f"--out {self.path} is a file, not a folder")
        try:
            self.path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ResultsError(f"cannot create the results folder {self.path}: {exc.strerror or exc}") from None
        self._lock()
        if fresh:
            self._clear_previous_run()
        self._reserve_summary()
        self._snapshots: dict[str, list[tuple[float, str]]] = {}

    # -- holding the folder ---------------------------------------------------
    def _lock(self) -> None:
        """Take ``.lock`` (our PID); refuse a folder a live run holds, take over a dead run's."""
        lock = self.path / ".lock"
        try:
            other = int(lock.read_text().strip() or 0)
        except (FileNotFoundError, ValueError):
            other = 0
        if other and other != os.getpid() and _alive(other):
            raise ResultsError(f"{self.path} is in use by another run (PID {other}); choose another --out, "
                               f"or remove {lock} if that process is gone")
        try:
            lock.write_text(f"{os.getpid()}\n")
        except OSError as exc:
            raise ResultsError(f"the results folder {self.path} is not writable: {exc.strerror or exc}") from None
        self._lock_path = lock

    def release(self) -> None:
        """Give the folder up (the run is over)."""
        lock = getattr(self, "_lock_path", None)
        if lock is not None:
            lock.unlink(missing_ok=True)
            self._lock_path = None

    def _reserve_summary(self) -> None:
        path = self.path / "summary.json"
        placeholder = json.dumps({"status": "running", "pid": os.getpid()})
        try:
            with open(path, "w") as f:
                f.write(placeholder + " " * (self.RESERVE - len(placeholder) - 1) + "\n")
        except OSError as exc:
            raise ResultsError(f"cannot write in the results folder {self.path}: {exc.strerror or exc}") from None

    def _clear_previous_run(self) -> None:
        """Remove what an earlier run wrote here, so no stale row or snapshot survives this one."""
        stale = [self.path / name for name in ("series.csv", "summary.json", "checkpoint.pkl", "eta_lumen.csv")]
        for part in self.PARTS:
            stale += [self.path / f"{part}.pvd", *self.path.glob(f"{part}_[0-9][0-9][0-9][0-9][0-9][0-9].vtu")]
        stale += list(self.path.glob("*.png"))
        for path in stale:
            path.unlink(missing_ok=True)

    def keep_until(self, step: int, snapshots: Mapping[str, Sequence[tuple[float, str]]]) -> None:
        """Resuming after ``step``: drop the snapshots written later, restore the collections."""
        for part in self.PARTS:
            for path in self.path.glob(f"{part}_[0-9][0-9][0-9][0-9][0-9][0-9].vtu"):
                if int(path.stem.rsplit("_", 1)[1]) > step:
                    path.unlink()
        for name, entries in snapshots.items():
            self._snapshots[name] = [(float(t), file) for t, file in entries]
            _write_atomically(self.path / f"{name}.pvd", _pvd(self._snapshots[name]))

    @property
    def snapshots(self) -> dict[str, list[tuple[float, str]]]:
        """Every collection's (t, file) entries so far."""
        return {k: list(v) for k, v in self._snapshots.items()}

    def series(self, columns: Sequence[str], name: str = "series.csv", keep_until: int | None = None) -> SeriesWriter:
        """A writer of ``series.csv`` (or ``name``) with these columns (see :class:`SeriesWriter`)."""
        return SeriesWriter(self.path / name, columns, keep_until)

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
        _append_to_collection(self.path / f"{name}.pvd", entries)
        return self.path / file

    def write_json(self, name: str, data: Mapping[str, Any]) -> Path:
        """Write ``name`` as indented JSON (numpy scalars and arrays converted)."""
        path = self.path / name
        _write_atomically(path, json.dumps(data, indent=2, default=_jsonable, allow_nan=True) + "\n")
        return path

    def write_summary(self, summary: Mapping[str, Any]) -> Path:
        """Write ``summary.json``: atomically, or into the room reserved at the start when the disk is full."""
        text = json.dumps(summary, indent=2, default=_jsonable, allow_nan=True) + "\n"
        path = self.path / "summary.json"
        try:
            _write_atomically(path, text)
        except OSError as exc:
            if exc.errno not in (errno.ENOSPC, errno.EDQUOT):
                raise
            (path.with_name(path.name + ".tmp")).unlink(missing_ok=True)
            compact = json.dumps(summary, default=_jsonable, allow_nan=True)
            if len(compact.encode()) >= self.RESERVE:  # keep what matters
                compact = json.dumps({k: summary[k] for k in ("status", "reason", "steps") if k in summary})
            with open(path, "r+") as f:  # the reserved blocks: no new space needed
                f.write(compact)
                f.truncate()
        return path


_PVD_HEAD = '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n  <Collection>\n'
_PVD_TAIL = "  </Collection>\n</VTKFile>\n"


def _dataset(t: float, file: str) -> str:
    stamp = repr(float(t)) if math.isfinite(t) else "0"  # the shortest text that reads back to t
    return f'    <DataSet timestep="{stamp}" group="" part="0" file={quoteattr(file)}/>\n'


def _pvd(entries: Sequence[tuple[float, str]]) -> str:
    """A ParaView collection of ``(t, file)`` snapshots."""
    return _PVD_HEAD + "".join(_dataset(t, f) for t, f in entries) + _PVD_TAIL


def _append_to_collection(path: Path, entries: Sequence[tuple[float, str]]) -> None:
    """Add the last entry to the collection at ``path``: overwrite the closing tags only (O(1))."""
    if len(entries) == 1 or not path.is_file():
        _write_atomically(path, _pvd(entries))
        return
    with open(path, "r+b") as f:
        f.seek(-len(_PVD_TAIL.encode()), os.SEEK_END)
        f.write((_dataset(*entries[-1]) + _PVD_TAIL).encode())


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process: alive
        return True
    return True


def holds_finished_run(folder: Path, digest: str) -> bool:
    """True when ``folder`` holds a run of the case with ``digest`` that ended ok (its ``summary.json`` says so)."""
    try:
        summary = json.loads((Path(folder) / "summary.json").read_text())
    except (OSError, ValueError):
        return False
    return summary.get("status") == "ok" and summary.get("case_hash") == digest
