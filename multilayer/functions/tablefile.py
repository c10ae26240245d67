"""Table files ``t, p`` read with bounds, and parsed.

A table file named by a case could be anything the file system holds (a
FIFO, a device, a file of gigabytes): :func:`read_bounded` refuses each with
a sentence before reading; :func:`parse_table` turns the text into strictly
increasing times and their values, naming the line of a bad row.  The load
built on them is :class:`multilayer.functions.loads.TablePressure`.
"""

from __future__ import annotations

import hashlib
import math
import os
import stat
from pathlib import Path

import numpy as np

#: The largest table file read (bytes): 10 MB is some 400 000 rows ``t, p``.
MAX_TABLE_BYTES = 10_000_000


class FileRefused(ValueError):
    """A file that is not read: the message says why, in the user's words."""


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def size_text(n: float) -> str:
    """A byte count for a message.

    >>> size_text(1_000_000), size_text(10_000_000), size_text(2500)
    ('1 MB', '10 MB', '2.5 kB')
    """
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n:.0f} bytes"


def read_bounded(path: Path | str, limit: int, what: str = "file") -> bytes:
    """The bytes of ``path``, a regular file of at most ``limit`` bytes.

    Raises
    ------
    FileNotFoundError
        When there is no such file.
    FileRefused
        When it is a directory, a FIFO, a device or a socket, or larger
        than ``limit`` (the message names which and says it is the ``what``).
    OSError
        When it cannot be read otherwise (permissions).
    """
    path = Path(path)
    mode = os.stat(path).st_mode  # FileNotFoundError: the caller's message
    if not stat.S_ISREG(mode):
        raise FileRefused(f"{_kind(mode)}, not a regular file; expected a {what}")
    # no blocking: a file swapped for a FIFO after the stat must not hang the open
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    with os.fdopen(fd, "rb") as handle:
        info = os.fstat(handle.fileno())
        if not stat.S_ISREG(info.st_mode):
            raise FileRefused(f"{_kind(info.st_mode)}, not a regular file; expected a {what}")
        if info.st_size > limit:
            raise FileRefused(f"{size_text(info.st_size)}; expected a {what} of at most {size_text(limit)}")
        data = handle.read(limit + 1)
    if len(data) > limit:  # it grew while read
        raise FileRefused(f"more than {size_text(limit)}; expected a {what} of at most {size_text(limit)}")
    return data


#: Times of a table beyond ±this (s) are a mistake (a unit, a typo), not a waveform; so is a longer period.
MAX_TABLE_TIME = 1e9


def read_table(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a two-column CSV ``t, p`` (an optional header line, ``#`` comments).

    The file must be a regular file of at most :data:`MAX_TABLE_BYTES`
    (a FIFO, a device, a directory are refused before they are read).

    Raises ValueError naming the line of a bad row (:class:`FileRefused`
    for a file that is not read; FileNotFoundError, OSError).
    """
    return read_csv(path)[:2]


def read_csv(path: Path) -> tuple[np.ndarray, np.ndarray, str]:
    """(times, values, SHA-256 of the bytes) of a table file, read once and with bounds."""
    raw = read_bounded(path, MAX_TABLE_BYTES, "table file")
    return (*parse_table(raw.decode("utf-8")), hashlib.sha256(raw).hexdigest())


def parse_table(text: str) -> tuple[np.ndarray, np.ndarray]:
    """The rows ``t, p`` of a table's text; ValueError naming the line of a bad row.

    >>> parse_table("t,p\\n0,1\\n1e308,2\\n")
    Traceback (most recent call last):
    ...
    ValueError: line 3: the time 1e+308 s is outside [-1e+09, 1e+09] s
    """
    rows: list[tuple[float, float]] = []
    lines: list[int] = []
    for number, line in enumerate(text.splitlines(), start=1):
        body = line.split("#", 1)[0].strip()
        if not body:
            continue
        fields = [f.strip() for f in (body.split(",") if "," in body else body.split())]
        try:
            t, p = (float(f) for f in fields)
        except ValueError:
            if not rows and not any(_is_number(f) for f in fields):
                continue  # the header line
            raise ValueError(f"line {number}: expected two numbers 't, p', got {line.strip()!r}") from None
        if not (math.isfinite(t) and math.isfinite(p)):
            raise ValueError(f"line {number}: every t and p must be a finite number, got {line.strip()!r}")
        if abs(t) > MAX_TABLE_TIME:
            raise ValueError(f"line {number}: the time {t:g} s is outside [{-MAX_TABLE_TIME:g}, {MAX_TABLE_TIME:g}] s")
        rows.append((t, p))
        lines.append(number)
    if len(rows) < 2:
        raise ValueError("expected at least two rows 't, p'")
    data = np.array(rows)
    steps = np.diff(data[:, 0])
    if np.any(steps <= 0):
        i = int(np.argmax(steps <= 0))
        raise ValueError(f"line {lines[i + 1]}: the times t must increase strictly from row to row "
                         f"({data[i + 1, 0]:g} s after {data[i, 0]:g} s)")
    return data[:, 0], data[:, 1]


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
