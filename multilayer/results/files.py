"""Files of a results folder written safely: never through a link, whole or not at all, rows that are whole.

* :func:`open_nofollow` refuses a symbolic link (``O_NOFOLLOW``);
* :func:`atomic_file`, :func:`write_atomically`, :func:`write_with` write a
  new ``.<name>.<8 hex>.tmp`` (``O_EXCL``) and rename it over the file, and
  remove it when the writing fails (a full disk, a signal): a file is
  replaced whole or left as it was;
* :class:`SeriesWriter` appends rows to a CSV file; a row that cannot be
  written whole is cut off again, so the file ends on a complete row.
"""

from __future__ import annotations

import csv
import errno
import io
import os
import secrets
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import numpy as np

NOFOLLOW = os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0)


def _cell(value: Any) -> Any:
    if isinstance(value, float | np.floating):
        return repr(float(value))  # shortest text that reads back to the same double
    return value


class ResultsError(Exception):
    """The results folder cannot be used (not writable, held by another run, not ours); the message says why."""


# -- files that are never opened through a link --------------------------------------------------------------
def open_nofollow(path: Path, flags: int, mode: str, **kwargs: Any) -> IO:
    """``open`` of ``path`` that refuses a symbolic link (``O_NOFOLLOW``)."""
    try:
        fd = os.open(path, flags | NOFOLLOW, 0o666)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise ResultsError(f"{path} is a symbolic link: not followed, not written") from None
        raise
    return os.fdopen(fd, mode, **({"newline": ""} if "b" not in mode else {}), **kwargs)


def new_temp(path: Path) -> tuple[int, Path]:
    """A new, empty ``.<name>.<8 hex>.tmp`` next to ``path`` (``O_CREAT | O_EXCL``: never an existing file)."""
    for _ in range(100):
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
        try:
            return os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | NOFOLLOW, 0o666), tmp
        except FileExistsError:
            continue
    raise ResultsError(f"no free temporary name next to {path}")


@contextmanager
def atomic_file(path: Path | str, mode: str = "wb") -> Iterator[IO]:
    """A new file that replaces ``path`` when the block ends without an error (none is left otherwise).

    The file is a fresh temporary (``O_CREAT | O_EXCL``), renamed over
    ``path``: a symbolic link at ``path`` is replaced, never followed.
    """
    path = Path(path)
    fd, tmp = new_temp(path)
    try:
        with os.fdopen(fd, mode, **({"newline": ""} if "b" not in mode else {})) as f:
            yield f
        os.replace(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        _name(exc, path)
        raise


def _name(exc: BaseException, path: Path) -> None:
    """Name ``path`` in an OSError that names no file (a write to a descriptor: the disk is full)."""
    if isinstance(exc, OSError) and (exc.filename is None or str(exc.filename).endswith(".tmp")):
        exc.filename = str(path)


def write_atomically(path: Path, text: str) -> None:
    with atomic_file(path, "w") as f:
        f.write(text)


def write_with(path: Path, write: Callable[[Path], None]) -> None:
    """``write(name)`` a file by its name (a library that opens it itself), atomically as :func:`atomic_file`."""
    fd, tmp = new_temp(path)
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        _name(exc, path)
        raise


class SeriesWriter:
    """Appends rows to a CSV file, header first, each row on disk before ``append`` returns.

    With ``keep_until`` (a resumed run) the file is kept, cut after the last row
    whose ``step`` is ≤ ``keep_until``, and must have the same columns.
    """

    def __init__(self, path: Path, columns: Sequence[str], keep_until: int | None = None):
        self.path = path
        self.columns = list(columns)
        self._known = frozenset(self.columns)
        self._before_last: int | None = None  # the file's size before the last row appended
        if keep_until is not None and path.is_file() and not path.is_symlink():
            self._cut(keep_until)
            return
        write_atomically(self.path, _csv([self.columns]))

    def _cut(self, step: int) -> None:
        with open_nofollow(self.path, os.O_RDONLY, "r") as f:
            rows = list(csv.reader(f))
        if not rows or rows[0] != self.columns:
            raise ResultsError(f"{self.path} does not have the columns of this run: cannot resume into it")
        kept = [r for r in rows[1:] if r and int(float(r[0])) <= step]
        write_atomically(self.path, _csv([rows[0], *kept]))

    def append(self, row: Mapping[str, Any]) -> None:
        """Write one row, whole or not at all; a column the row lacks is left empty, an unknown key is an error.

        When the row cannot be written (a full disk), what reached the file
        of it is cut off again (cutting needs no space) and the OSError,
        naming the file, is raised: the file still ends on its last whole row.
        """
        unknown = row.keys() - self._known
        if unknown:
            raise KeyError(f"not columns of {self.path.name}: {sorted(unknown)}")
        data = _csv([[_cell(row.get(c, "")) for c in self.columns]]).encode()
        with open_nofollow(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, "ab", buffering=0) as f:
            fd = f.fileno()
            end = os.fstat(fd).st_size
            try:
                written = 0
                while written < len(data):
                    written += os.write(fd, data[written:])
            except BaseException as exc:
                os.ftruncate(fd, end)
                _name(exc, self.path)
                raise
        self._before_last = end

    def undo(self) -> None:
        """Cut the last row appended off again (its partner file could not take its row)."""
        if self._before_last is not None:
            with open_nofollow(self.path, os.O_WRONLY, "ab", buffering=0) as f:
                os.ftruncate(f.fileno(), self._before_last)
            self._before_last = None


def _csv(rows: Iterable[Sequence[Any]]) -> str:
    text = io.StringIO(newline="")
    csv.writer(text).writerows(rows)
    return text.getvalue()

