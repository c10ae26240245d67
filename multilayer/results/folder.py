"""The results folder of a run: a time series, field snapshots, a summary.

Everything is written so that a run that dies half-way leaves readable
files: ``series.csv`` gets every row as soon as it is appended, each
``<name>.pvd`` collection is valid after every snapshot (a new entry
overwrites only the closing tags, so a snapshot costs the same however many
came before), and ``summary.json`` has its room reserved on disk when the
run starts, so it is written even when the disk fills up.

A folder owns only what it wrote: ``manifest.json`` lists its files of
fixed names (:data:`FIXED`, claimed when it starts) and each snapshot
(listed before it is written, with the next ones at its stride: O(log n)
rewrites; those not reached are dropped at the end).  A new run deletes
the previous manifest's files, nothing else; a resume drops only its
snapshots after the checkpoint; a file of a run's name it did not write
stops the run.  Nothing is opened through a symbolic link (``O_NOFOLLOW``);
whole rewrites go to a new ``.<name>.<8 hex>.tmp`` (``O_EXCL``), renamed.
One run at a time: ``.lock``, ``flock``'d, with PID and host (a dead
holder's is taken over).  A new run refuses the current directory, ``/``,
home and a non-empty foreign folder unless ``force``.
"""

from __future__ import annotations

import errno
import json
import math
import os
import re
import secrets
from collections.abc import Mapping, Sequence
from contextlib import suppress
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np

from multilayer.results import lock
from multilayer.results.files import (
    ResultsError,
    SeriesWriter,
    open_nofollow,
    write_atomically,
    write_with,
)
from multilayer.results.lock import LOCK

#: the list of the files a run owns
MANIFEST = "manifest.json"
#: what ``manifest.json`` says it is
FORMAT = "multilayer results folder"
#: the figures of a run (:mod:`multilayer.results.figures`)
FIGURES = ("eta_spacetime.png", "probes.png", "energy.png", "wss.png", "cycles.png")
#: the files of fixed names a run may write: all claimed in the manifest when it starts
FIXED = ("summary.json", "series.csv", "eta_lumen.csv", "wss_lumen.csv", "checkpoint.json", "checkpoint.npz",
         "wall.pvd", "fluid.pvd", "lumen.pvd", *FIGURES)
#: a temporary of this module: ``.<name>.<8 hex digits>.tmp``
_TEMP = re.compile(r"\.(.+)\.[0-9a-f]{8}\.tmp")
_SNAPSHOT = re.compile(r"(.+)_([0-9]{6})\.vtu")


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


# -- what a folder owns ----------------------------------------------------------------------------------------
def owned_files(folder: Path | str) -> frozenset[str] | None:
    """The names of the files a run of multilayer owns in ``folder``; None when it is not a results folder.

    From ``manifest.json``; a folder of a multilayer without manifests (its
    ``summary.json`` says it is ours) owns the files of fixed names and the
    snapshots of :attr:`ResultsFolder.PARTS`, as that version wrote them.
    """
    folder = Path(folder)
    manifest = read_manifest(folder)
    if isinstance(manifest, dict) and manifest.get("format") == FORMAT and isinstance(manifest.get("files"), list):
        listed = manifest["files"]
        strangers = [name for name in listed if not _written_by_a_run(name)]
        if strangers:  # the manifest is data: it names files, it does not choose which a run may remove
            raise ResultsError(f"{folder / MANIFEST} lists {strangers[0]!r}"
                               f"{f' and {len(strangers) - 1} more' if len(strangers) > 1 else ''}, not a file a run "
                               f"of multilayer writes in its folder: refused, nothing touched (a run owns only "
                               f"{', '.join(FIXED[:3])}, … and its snapshots <part>_<step>.vtu, directly inside "
                               f"the folder)")
        return frozenset(listed) | {MANIFEST}
    if manifest is not None or (folder / MANIFEST).is_symlink():
        return None  # someone else's manifest.json
    try:
        with open_nofollow(folder / "summary.json", os.O_RDONLY, "r") as f:
            summary = json.load(f)
    except (OSError, ValueError, ResultsError):
        return None
    if not isinstance(summary, dict) or not ({"case_hash", "multilayer_version"} & summary.keys()
                                             or summary.keys() == {"status", "pid"}):
        return None
    snapshots = {name for name in _names(folder) if snapshot_of(name)}
    return frozenset({*FIXED, *snapshots})


def read_manifest(folder: Path | str) -> Any:
    """``folder``'s ``manifest.json`` as parsed JSON (never read through a link); None when it cannot be read."""
    try:
        with open_nofollow(Path(folder) / MANIFEST, os.O_RDONLY, "r") as f:
            return json.load(f)
    except (OSError, ValueError, RecursionError, ResultsError):
        return None


def run_identity(folder: Path | str) -> str | None:
    """The identity of the run that owns ``folder`` (its manifest's ``run``); None when it records none."""
    manifest = read_manifest(folder)
    run = manifest.get("run") if isinstance(manifest, dict) else None
    return run if isinstance(run, str) else None


def snapshot_of(name: object) -> tuple[str, int] | None:
    """(part, step) when ``name`` is a snapshot a run writes, ``<part>_<step>.vtu`` of a part of
    :attr:`ResultsFolder.PARTS`; None for any other name."""
    m = _SNAPSHOT.fullmatch(name) if isinstance(name, str) else None
    return (m[1], int(m[2])) if m is not None and m[1] in ResultsFolder.PARTS else None


def _written_by_a_run(name: object) -> bool:
    """True for a name a run of multilayer writes directly inside its folder: a fixed name or a snapshot."""
    return name in FIXED or name == MANIFEST or snapshot_of(name) is not None


def may_write(folder: Path | str, name: str) -> bool:
    """True when writing ``folder/name`` clobbers nothing of anyone else: it is the folder's own, or new."""
    folder = Path(folder)
    return not os.path.lexists(folder / name) or name in (owned_files(folder) or ())


def _names(folder: Path) -> list[str]:
    return os.listdir(folder) if folder.is_dir() else []


def _is_ours_in_passing(name: str) -> bool:  # what another run's start leaves in an empty folder
    return name == LOCK or ((m := _TEMP.fullmatch(name)) is not None and m[1] in (MANIFEST, *FIXED))


def dangerous(path: Path) -> str:
    """Why ``path`` must not be a new run's results folder (without ``--force``), or ''."""
    resolved = path.resolve()
    if resolved == Path.cwd().resolve():
        return "is the current directory"
    if resolved == Path(resolved.anchor):
        return "is the root of the file system"
    try:
        if resolved == Path.home().resolve():
            return "is your home folder"
    except RuntimeError:  # no home
        pass
    return ""


def _foreign(path: Path) -> bool:
    """True when ``path`` holds files but no results of multilayer."""
    # listed first: a run starting here writes its manifest before any other file
    return any(not _is_ours_in_passing(n) for n in _names(path)) and owned_files(path) is None


class ResultsFolder:
    """The output folder of one run.

    ``fresh`` (a new run): the files of the previous run here are deleted;
    otherwise (a resume) they are kept.  A new run refuses a dangerous
    folder (see the module) unless ``force``.

    Examples
    --------
    >>> import tempfile
    >>> out = ResultsFolder(Path(tempfile.mkdtemp()) / "run")
    >>> series = out.series(["step", "t"])
    >>> series.append({"step": 1, "t": 1e-4})
    >>> (out.path / "series.csv").read_text().splitlines()
    ['step,t', '1,0.0001']
    >>> out.release()
    """

    #: the parts a run writes snapshots of
    PARTS = ("wall", "fluid", "lumen")
    #: bytes kept on disk for summary.json from the start of a run
    RESERVE = 1 << 16

    def __init__(self, out: Path | str, fresh: bool = True, force: bool = False):
        self._lock_fd: int | None = None
        self._owned: set[str] = set()
        #: the identity of the run that owns the folder (its manifest's ``run``): a checkpoint carries it
        self.run_id: str | None = None
        self._ahead: set[str] = set()  # snapshots claimed before their step came (see _claim_snapshot)
        self._last: dict[str, tuple[int, int]] = {}  # per collection: its last snapshot's step, snapshots claimed
        self._snapshots: dict[str, list[tuple[float, str]]] = {}
        if isinstance(out, str) and not out.strip():
            raise ResultsError("--out is empty: name the results folder")
        self.path = Path(out)
        checked = fresh and not force
        try:  # a path the system cannot follow (a link loop) or name (too long) is refused as such
            why = dangerous(self.path) if checked else ""
            exists, is_dir = self.path.exists(), self.path.is_dir()
            foreign = checked and is_dir and _foreign(self.path)
        except (RuntimeError, OSError) as exc:
            raise ResultsError(f"--out {str(out)[:80]}{'…' if len(str(out)) > 80 else ''} cannot be used as a "
                               f"results folder: {getattr(exc, 'strerror', None) or exc}") from None
        if why:
            raise ResultsError(f"--out {out} {why}: choose a folder of its own (or --force)")
        if exists and not is_dir:
            raise NotADirectoryError(f"--out {self.path} is a file, not a folder")
        if foreign:
            raise ResultsError(_not_ours(self.path))
        created = not exists
        try:
            self.path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ResultsError(f"cannot create the results folder {self.path}: {exc.strerror or exc}") from None
        self._hold()
        try:
            self._take_over(fresh, force)
            self._reserve_summary()
        except BaseException:  # a full disk, a signal: nothing half-made is left
            if created:  # every file in it is this run's
                with suppress(OSError, ResultsError):
                    self._remove("summary.json")
                    self._remove(MANIFEST)
            self.release()
            if created:
                with suppress(OSError):
                    self.path.rmdir()
            raise

    # -- holding the folder ---------------------------------------------------
    def _hold(self) -> None:
        """Take ``.lock`` (:mod:`multilayer.results.lock`); refuse a folder a live run holds."""
        self._lock_fd = lock.take(self.path)

    def release(self) -> None:
        """Give the folder up (the run is over): ``.lock`` is removed."""
        fd, self._lock_fd = getattr(self, "_lock_fd", None), None
        if fd is None:
            return
        unwritten = {name for name in self._ahead if not os.path.lexists(self.path / name)}
        if unwritten:  # the snapshots claimed ahead that the run did not reach
            self._owned -= unwritten
            self._ahead.clear()
            try:
                self._write_manifest()
            except ResultsError:
                pass
        lock.release(self.path, fd)

    def __del__(self) -> None:
        with suppress(Exception):  # the interpreter may be shutting down
            self.release()

    # -- what the folder owns -----------------------------------------------------
    def _take_over(self, fresh: bool, force: bool) -> None:
        previous = owned_files(self.path)
        if previous is None and (not fresh or (not force and _foreign(self.path))):
            raise ResultsError(_not_ours(self.path) if fresh else
                               f"{self.path} is not a results folder of multilayer (no {MANIFEST}): cannot resume")
        previous = set(previous or ())
        names = _names(self.path)
        wanted = {MANIFEST, *FIXED} | {n for n in names if snapshot_of(n)}
        clash = sorted(n for n in names if n in wanted and n not in previous)
        if clash:
            raise ResultsError(f"{self.path} holds {', '.join(clash[:3])}{' …' if len(clash) > 3 else ''} that no "
                               f"run of multilayer wrote there: move it away or choose another --out")
        folders = sorted(n for n in previous if n in names and (self.path / n).is_dir() and not (self.path / n).is_symlink())
        if folders:  # checked before anything is removed: a run's files are files
            raise ResultsError(f"{self.path / folders[0]} is a folder, not a file of a run: move it away or "
                               f"choose another --out (nothing touched)")
        for name in names:  # temporaries a run killed while writing left behind
            if (m := _TEMP.fullmatch(name)) and m[1] in previous | {MANIFEST, *FIXED}:
                self._remove(name)
        if fresh:
            for name in sorted(previous - {MANIFEST}):
                self._remove(name)
            previous = set()
        self.run_id = secrets.token_hex(8) if fresh else run_identity(self.path)
        self._owned = previous | set(FIXED)
        self._write_manifest()

    def _remove(self, name: str) -> None:
        try:
            (self.path / name).unlink()
        except FileNotFoundError:
            pass
        except IsADirectoryError:
            raise ResultsError(f"{self.path / name} is a folder: not a file of the run, not removed") from None
        except OSError as exc:
            raise ResultsError(f"cannot remove {self.path / name}: {exc.strerror or exc}") from None

    def _write_manifest(self) -> None:
        manifest = {"format": FORMAT, "files": sorted(self._owned - {MANIFEST}),
                    **({"run": self.run_id} if self.run_id is not None else {})}
        try:
            write_atomically(self.path / MANIFEST, json.dumps(manifest, indent=1) + "\n")
        except OSError as exc:
            raise ResultsError(f"cannot write in the results folder {self.path}: {exc.strerror or exc}") from None

    def claim(self, name: str) -> Path:
        """Own ``name`` (listed in the manifest before it is written); refuse a file of that name not ours."""
        if name not in self._owned:
            if os.path.lexists(self.path / name):
                raise ResultsError(f"{self.path / name} was not written by this run: not overwritten")
            self._owned.add(name)
            self._write_manifest()
        return self.path / name

    def _claim_snapshot(self, name: str, step: int) -> Path:
        """:meth:`claim` ``<name>_<step>.vtu``, and the next ones at the same stride, as many as claimed so far.

        The manifest is rewritten O(log n) times for n snapshots, not n
        times; :meth:`release` drops from it the claimed ones not written.
        """
        file = f"{name}_{step:06d}.vtu"
        self._ahead.discard(file)
        last, claimed = self._last.get(name, (None, 0))
        self._last[name] = (step, claimed)
        if file in self._owned:
            return self.path / file
        if os.path.lexists(self.path / file):
            raise ResultsError(f"{self.path / file} was not written by this run: not overwritten")
        stride = step - last if last is not None and step > last else 0
        new = [file]
        for k in range(1, min(max(claimed, 1), 4096) + 1 if stride else 1):
            if step + k * stride > 999999:
                break
            ahead = f"{name}_{step + k * stride:06d}.vtu"
            if ahead not in self._owned and not os.path.lexists(self.path / ahead):
                new.append(ahead)
                self._ahead.add(ahead)
        self._owned.update(new)
        self._last[name] = (step, claimed + len(new))
        self._write_manifest()
        return self.path / file

    def _reserve_summary(self) -> None:
        path = self.claim("summary.json")
        placeholder = json.dumps({"status": "running", "pid": os.getpid()})
        try:
            with open_nofollow(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, "w") as f:
                f.write(placeholder + " " * (self.RESERVE - len(placeholder) - 1) + "\n")
        except BaseException as exc:  # no half-reserved summary is left
            with suppress(OSError):
                path.unlink()
            if isinstance(exc, OSError):
                raise ResultsError(f"cannot write in the results folder {self.path}: {exc.strerror or exc}") from None
            raise

    def keep_until(self, step: int, snapshots: Mapping[str, Sequence[tuple[float, str]]]) -> None:
        """Resuming after ``step``: drop the snapshots written later, restore the collections."""
        later = [name for name in self._owned if (snapshot := snapshot_of(name)) and snapshot[1] > step]
        for name in later:
            self._remove(name)
        if later:
            self._owned -= set(later)
            self._write_manifest()
        for name, entries in snapshots.items():
            self._snapshots[name] = [(float(t), file) for t, file in entries]
            write_atomically(self.claim(f"{name}.pvd"), _pvd(self._snapshots[name]))

    @property
    def snapshots(self) -> dict[str, list[tuple[float, str]]]:
        """Every collection's (t, file) entries so far."""
        return {k: list(v) for k, v in self._snapshots.items()}

    def series(self, columns: Sequence[str], name: str = "series.csv", keep_until: int | None = None) -> SeriesWriter:
        """A writer of ``series.csv`` (or ``name``) with these columns (see :class:`SeriesWriter`)."""
        return SeriesWriter(self.claim(name), columns, keep_until)

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
        collection = self.claim(f"{name}.pvd")
        mesh = meshio.Mesh(points, dict(cells), point_data=data)
        write_with(self._claim_snapshot(name, step), lambda tmp: meshio.write(tmp, mesh, file_format="vtu"))
        entries = self._snapshots.setdefault(name, [])
        entries.append((float(t), file))
        _append_to_collection(collection, entries)
        return self.path / file

    def write_json(self, name: str, data: Mapping[str, Any]) -> Path:
        """Write ``name`` as indented JSON (numpy scalars and arrays converted)."""
        path = self.claim(name)
        write_atomically(path, json.dumps(data, indent=2, default=_jsonable, allow_nan=True) + "\n")
        return path

    def write_summary(self, summary: Mapping[str, Any]) -> Path:
        """Write ``summary.json``: atomically, or into the room reserved at the start when the disk is full."""
        text = json.dumps(summary, indent=2, default=_jsonable, allow_nan=True) + "\n"
        path = self.claim("summary.json")
        try:
            write_atomically(path, text)
        except OSError as exc:
            if exc.errno not in (errno.ENOSPC, errno.EDQUOT):
                raise
            compact = json.dumps(summary, default=_jsonable, allow_nan=True)
            if len(compact.encode()) >= self.RESERVE:  # keep what matters
                compact = json.dumps({k: summary[k] for k in ("status", "reason", "steps") if k in summary})
            with open_nofollow(path, os.O_RDWR, "r+") as f:  # the reserved blocks: no new space needed
                f.write(compact)
                f.truncate()
        return path


def _not_ours(path: Path) -> str:
    return (f"--out {path} is not empty and not a results folder of multilayer (no {MANIFEST}): choose another "
            f"--out, or --force to write into it (the run touches only its own files)")


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
    if len(entries) == 1 or not path.is_file() or path.is_symlink():
        write_atomically(path, _pvd(entries))
        return
    with open_nofollow(path, os.O_RDWR, "r+b") as f:
        f.seek(-len(_PVD_TAIL.encode()), os.SEEK_END)
        f.write((_dataset(*entries[-1]) + _PVD_TAIL).encode())


def holds_finished_run(folder: Path, digest: str) -> bool:
    """True when ``folder`` holds a run of the case with ``digest`` that ended ok (its ``summary.json`` says so)."""
    try:
        with open_nofollow(Path(folder) / "summary.json", os.O_RDONLY, "r") as f:
            summary = json.load(f)
    except (OSError, ValueError, ResultsError):
        return False
    return summary.get("status") == "ok" and summary.get("case_hash") == digest
