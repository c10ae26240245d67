"""Pressure loads P(t): inlet, outlet, external and interface pressures.

The scheme never samples a pressure at a point in time: it uses the time
average Pⁿ = (1/Δt) ∫ P dt over [tⁿ, tⁿ⁺¹] (theory §6).  Every load therefore
knows its exact integral where a closed form exists (constant, cosine pulse,
sine, piecewise-linear table) and a 5-point Gauss–Legendre rule otherwise
(formula).

A case file writes a load as a number (constant), a string (formula in
``t``) or a table ``{kind = "...", ...}``; :func:`load_from_spec` turns any
of them into a :class:`PressureLoad` or raises a
:class:`~multilayer.plugin.problems.CaseError` naming the key path.  The
same kinds serve another quantity given as a function of t (a flow rate):
the caller names its unit, in which the messages speak.
"""

from __future__ import annotations

import hashlib
import math
import os
import stat
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar

import attrs
import numpy as np

from multilayer.functions.formula import Formula, FormulaError
from multilayer.plugin.problems import (
    MISSING,
    CaseError,
    Problem,
    check_params,
    did_you_mean,
)
from multilayer.plugin.records import Param

#: the unit of the values of the load kinds (:data:`KINDS`): a pressure's
PRESSURE_UNIT = "dyn/cm²"


class LoadSpec(ABC):
    """The type of a plugin parameter whose value is a load as a case writes it, for :func:`load_from_spec`:
    a number, a formula in t or a table ``{kind = ...}`` (``Param("flow", type=LoadSpec)``).

    >>> isinstance(2.0, LoadSpec), isinstance("sin(t)", LoadSpec), isinstance({"kind": "sine"}, LoadSpec)
    (True, True, True)
    >>> isinstance(True, LoadSpec), isinstance([1.0], LoadSpec)
    (False, False)
    """

    #: what a value of this type is, in the words of a validation message
    noun: ClassVar[str] = "a number, a formula in t or a table {kind = ...}"

    @classmethod
    def __subclasshook__(cls, other: type) -> bool:
        return not issubclass(other, bool) and issubclass(other, int | float | str | Mapping)


def is_zero(load: PressureLoad | None) -> bool:
    """True for a load that is absent or the constant 0 (the default of every load).

    >>> is_zero(ConstantPressure(0.0)), is_zero(ConstantPressure(1.0))
    (True, False)
    """
    return load is None or (isinstance(load, ConstantPressure) and load.value_ == 0.0)


class PressureLoad(ABC):
    """A pressure history P(t) in dyn/cm²."""

    kind: ClassVar[str]

    @abstractmethod
    def value(self, t: Any) -> Any:
        """P(t); vectorised over ``t``."""

    @abstractmethod
    def integral(self, t0: float, t1: float) -> float:
        """∫ P dt over [t0, t1]."""

    def average(self, t0: float, t1: float) -> float:
        """(1/(t1 − t0)) ∫ P dt over [t0, t1]: the pressure a step [t0, t1] sees."""
        if t1 == t0:
            return float(self.value(t0))
        return float(self.integral(t0, t1)) / (t1 - t0)

    @abstractmethod
    def to_dict(self) -> dict[str, Any]:
        """The load as case-file data (JSON-able, defaults filled)."""


@attrs.frozen
class ConstantPressure(PressureLoad):
    """P(t) = value.

    >>> ConstantPressure(3.0).average(0.0, 0.1)
    3.0
    """

    kind: ClassVar[str] = "constant"
    value_: float = attrs.field(converter=float, alias="value")

    def value(self, t: Any) -> Any:
        return self.value_ + 0.0 * np.asarray(t, dtype=float)

    def integral(self, t0: float, t1: float) -> float:
        return self.value_ * (t1 - t0)

    def average(self, t0: float, t1: float) -> float:
        return self.value_

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "value": self.value_}


@attrs.frozen
class CosinePulse(PressureLoad):
    """P = amplitude/2 · (1 − cos(2πt/duration)) for 0 ≤ t ≤ duration, 0 otherwise.

    The inlet pulse of the reference scene (theory §9): amplitude = P_max.

    >>> p = CosinePulse(amplitude=2.0, duration=1.0)
    >>> float(p.value(0.5)), p.average(0.0, 1.0), p.average(1.0, 2.0)
    (2.0, 1.0, 0.0)
    """

    kind: ClassVar[str] = "cosine-pulse"
    amplitude: float = attrs.field(converter=float)  #: P_max (dyn/cm²)
    duration: float = attrs.field(converter=float)  #: t_max (s)

    def value(self, t: Any) -> Any:
        t = np.asarray(t, dtype=float)
        inside = (t >= 0.0) & (t <= self.duration)
        return np.where(inside, 0.5 * self.amplitude * (1.0 - np.cos(2.0 * np.pi * t / self.duration)), 0.0)

    def _antiderivative(self, t: float) -> float:
        s = min(max(t, 0.0), self.duration)
        return 0.5 * self.amplitude * (s - self.duration / (2.0 * math.pi) * math.sin(2.0 * math.pi * s / self.duration))

    def integral(self, t0: float, t1: float) -> float:
        return self._antiderivative(t1) - self._antiderivative(t0)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "amplitude": self.amplitude, "duration": self.duration}


@attrs.frozen
class SinePressure(PressureLoad):
    """P = mean + amplitude · sin(2π·frequency·t + phase).

    >>> p = SinePressure(amplitude=1.0, frequency=2.0, mean=5.0)
    >>> round(p.average(0.0, 0.5), 12)
    5.0
    """

    kind: ClassVar[str] = "sine"
    amplitude: float = attrs.field(converter=float)  #: dyn/cm²
    frequency: float = attrs.field(converter=float)  #: Hz
    mean: float = attrs.field(default=0.0, converter=float)  #: dyn/cm²
    phase: float = attrs.field(default=0.0, converter=float)  #: rad

    def value(self, t: Any) -> Any:
        t = np.asarray(t, dtype=float)
        return self.mean + self.amplitude * np.sin(2.0 * np.pi * self.frequency * t + self.phase)

    def integral(self, t0: float, t1: float) -> float:
        w = 2.0 * math.pi * self.frequency
        swing = (math.cos(w * t0 + self.phase) - math.cos(w * t1 + self.phase)) / w
        return self.mean * (t1 - t0) + self.amplitude * swing

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "amplitude": self.amplitude, "frequency": self.frequency,
                "mean": self.mean, "phase": self.phase}


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

    The file must be a regular file of at most :data:`~multilayer.case.files.MAX_TABLE_BYTES`
    (a FIFO, a device, a directory are refused before they are read).

    Raises ValueError naming the line of a bad row (:class:`~multilayer.case.files.FileRefused`
    for a file that is not read; FileNotFoundError, OSError).
    """
    return _read_csv(path)[:2]


def _read_csv(path: Path) -> tuple[np.ndarray, np.ndarray, str]:
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


@attrs.frozen(eq=False)
class TablePressure(PressureLoad):
    """Piecewise-linear P through the points (times, values), times ``scale``.

    Without a ``period`` the first and last values are held before and after
    the table.  With a ``period`` T the table is one cycle starting at its
    first time t₀ (it may span at most T; when it ends before t₀ + T the cycle
    closes linearly back to the first value) and repeats for ever.

    >>> p = TablePressure(np.array([0.0, 1.0]), np.array([0.0, 2.0]), period=2.0)
    >>> float(p.value(1.5)), p.average(0.0, 2.0), p.average(0.0, 4.0)
    (1.0, 1.0, 1.0)
    """

    kind: ClassVar[str] = "table"
    times: np.ndarray = attrs.field(converter=lambda a: np.asarray(a, dtype=float))
    values: np.ndarray = attrs.field(converter=lambda a: np.asarray(a, dtype=float))
    period: float | None = None  #: s; None: no repetition
    scale: float = attrs.field(default=1.0, converter=float)
    file: str = ""  #: the file as the case names it
    sha256: str = ""  #: of the file's bytes

    def __attrs_post_init__(self) -> None:
        if self.times.shape != self.values.shape or self.times.size < 2:
            raise ValueError("a table needs at least two points (t, p)")
        if not (np.all(np.isfinite(self.times)) and np.all(np.abs(self.times) <= MAX_TABLE_TIME)):
            raise ValueError(f"every time must be a finite number in [{-MAX_TABLE_TIME:g}, {MAX_TABLE_TIME:g}] s")
        if np.any(np.diff(self.times) <= 0):
            raise ValueError("the times t must increase strictly from row to row")
        if self.period is not None and not 0.0 < self.period <= MAX_TABLE_TIME:
            raise ValueError(f"the period must be a number in (0, {MAX_TABLE_TIME:g}] s")
        x, y = self._knots()
        with np.errstate(all="ignore"):
            area = float(np.sum(np.abs(0.5 * (y[1:] + y[:-1]) * np.diff(x))))
        if not (np.all(np.isfinite(y)) and math.isfinite(area)):
            raise ValueError("the pressures times the scale, or their integral over the table, overflow")
        if self.period is not None and self.times[-1] - self.times[0] > self.period * (1 + 1e-12):
            raise ValueError(
                f"the table spans {self.times[-1] - self.times[0]:g} s, more than one period ({self.period:g} s)"
            )

    @classmethod
    def from_csv(cls, path: Path, file: str = "", period: float | None = None, scale: float = 1.0) -> TablePressure:
        """Read ``path`` (see :func:`read_table`); ``file`` is the name as the case gives it."""
        times, values, digest = _read_csv(path)
        return cls(times, values, period=period, scale=scale, file=file or str(path), sha256=digest)

    def _knots(self) -> tuple[np.ndarray, np.ndarray]:
        x, y = self.times, self.scale * self.values
        if self.period is not None and x[-1] < x[0] + self.period:
            x, y = np.append(x, x[0] + self.period), np.append(y, y[0])
        return x, y

    def _within(self, t: np.ndarray) -> np.ndarray:
        """Map t into the table's time range (one cycle when periodic)."""
        if self.period is None:
            return t
        return self.times[0] + np.mod(t - self.times[0], self.period)

    def value(self, t: Any) -> Any:
        x, y = self._knots()
        return np.interp(self._within(np.asarray(t, dtype=float)), x, y)

    def _antiderivative(self, t: float) -> float:
        """∫ P from the first time t₀ to t, exact for the piecewise-linear P."""
        x, y = self._knots()
        cumulative = np.concatenate(([0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(x))))
        done = 0.0  # whole cycles before t
        if self.period is not None:
            # one divmod for both: floor and mod computed apart can disagree by a cycle at a boundary
            cycles, into = divmod(t - x[0], self.period)
            done = cycles * cumulative[-1]
            t = x[0] + into
        if t <= x[0]:
            return done + y[0] * (t - x[0])
        if t >= x[-1]:
            return done + cumulative[-1] + y[-1] * (t - x[-1])
        i = int(np.searchsorted(x, t, side="right")) - 1
        s, slope = t - x[i], (y[i + 1] - y[i]) / (x[i + 1] - x[i])
        return done + cumulative[i] + y[i] * s + 0.5 * slope * s * s

    def integral(self, t0: float, t1: float) -> float:
        return self._antiderivative(t1) - self._antiderivative(t0)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "file": self.file, "period": self.period, "scale": self.scale,
                "sha256": self.sha256}


_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(5)


@attrs.frozen
class FormulaPressure(PressureLoad):
    """P(t) given by a :class:`~multilayer.functions.formula.Formula` in ``t``.

    Its step average uses 5-point Gauss–Legendre (exact for polynomials of degree ≤ 9).

    >>> round(FormulaPressure(Formula.parse("3*t**2", variables=("t",))).average(0.0, 1.0), 12)
    1.0
    """

    kind: ClassVar[str] = "formula"
    formula: Formula

    def value(self, t: Any) -> Any:
        return self.formula(t=t)

    def integral(self, t0: float, t1: float) -> float:
        half = 0.5 * (t1 - t0)
        return half * float(_GAUSS_W @ self.formula(t=t0 + half * (_GAUSS_X + 1.0)))

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "expr": str(self.formula)}


#: Parameters of each load kind written as a table in a case file.
KINDS: dict[str, tuple[Param, ...]] = {
    "constant": (Param("value", "P", "dyn/cm²", doc="the pressure"),),
    "cosine-pulse": (
        Param("amplitude", "P_max", "dyn/cm²", doc="peak pressure"),
        Param("duration", "t_max", "s", gt=0.0, doc="length of the pulse"),
    ),
    "sine": (
        Param("amplitude", "", "dyn/cm²", doc="amplitude of the oscillation"),
        Param("frequency", "f", "Hz", gt=0.0, doc="frequency"),
        Param("mean", "", "dyn/cm²", default=0.0, doc="mean pressure"),
        Param("phase", "φ", "rad", default=0.0, doc="phase at t = 0"),
    ),
    "table": (
        Param("file", type=str, doc="CSV file t,p, relative to the case file's folder"),
        Param("period", "T", "s", default=None, gt=0.0, le=MAX_TABLE_TIME, doc="repeat the table with this period"),
        Param("scale", default=1.0, doc="factor applied to every p"),
        Param("sha256", type=str, default=None, doc="expected SHA-256 of the file (checked if given)"),
    ),
    "formula": (Param("expr", type=str, doc="a formula in t"),),
}


def load_from_spec(
    spec: Any, path: str, base_dir: Path | str = ".", constants: Mapping[str, float] | None = None,
    quantity: str = "pressure", unit: str = PRESSURE_UNIT,
) -> PressureLoad:
    """Build a load from its case-file form: a number, a formula string or a table.

    ``quantity`` and ``unit`` name what the values are, for the messages
    (a flow rate's values are in its own unit, not in dyn/cm²).

    Raises
    ------
    CaseError
        With problems at ``path`` (e.g. ``loads.inlet.duration``).

    Examples
    --------
    >>> load_from_spec(0, "loads.outlet").to_dict()
    {'kind': 'constant', 'value': 0.0}
    >>> round(load_from_spec("1e4*t", "loads.inlet").average(0.0, 2.0), 9)
    10000.0
    >>> load_from_spec({"kind": "cosine-pulse", "amplitude": 1.3333e4, "duration": 0.003}, "loads.inlet").kind
    'cosine-pulse'
    >>> load_from_spec({"kind": "cosine-puls", "amplitude": 1.0}, "loads.inlet")
    Traceback (most recent call last):
    ...
    multilayer.plugin.problems.CaseError: loads.inlet.kind = 'cosine-puls': no such pressure load kind; did you mean 'cosine-pulse'?
    >>> load_from_spec({"kind": "sine", "amplitude": "2"}, "loads.inlet.flow", quantity="flow rate", unit="cm²/s")
    Traceback (most recent call last):
    ...
    multilayer.plugin.problems.CaseError: loads.inlet.flow.amplitude = '2': expected a number (cm²/s)
    loads.inlet.flow.frequency: missing; expected a number > 0.0 (Hz)
    """
    if isinstance(spec, int | float) and not isinstance(spec, bool):
        if not math.isfinite(spec):
            raise CaseError([Problem(path, spec, f"expected a finite {quantity} ({unit})")])
        return ConstantPressure(spec)
    if isinstance(spec, str):
        return FormulaPressure(_formula(spec, path, constants))
    if not isinstance(spec, Mapping):
        raise CaseError([Problem(path, spec, "expected a number, a formula in t or a table {kind = ...}")])
    kind = spec.get("kind", MISSING)
    if not isinstance(kind, str) or kind not in KINDS:
        expected = f"no such {quantity} load kind" if kind is not MISSING else "missing; expected a load kind"
        hint = did_you_mean(kind, KINDS) if isinstance(kind, str) else ""
        raise CaseError([Problem(f"{path}.kind", kind, expected, hint or "kinds: " + ", ".join(KINDS))])
    params, problems = check_params(spec, in_unit(KINDS[kind], unit), path, extra=("kind",))
    if problems:
        raise CaseError(problems)
    if kind == "constant":
        return ConstantPressure(params["value"])
    if kind == "cosine-pulse":
        return CosinePulse(**params)
    if kind == "sine":
        return SinePressure(**params)
    if kind == "formula":
        return FormulaPressure(_formula(params["expr"], f"{path}.expr", constants))
    return _table(params, path, Path(base_dir))


def in_unit(params: Sequence[Param], unit: str) -> tuple[Param, ...]:
    """The load kind's parameters with their values in ``unit`` instead of dyn/cm² (times, frequencies stay).

    >>> [p.unit for p in in_unit(KINDS["sine"], "cm²/s")]
    ['cm²/s', 'Hz', 'cm²/s', 'rad']
    """
    return tuple(attrs.evolve(p, unit=unit) if p.unit == PRESSURE_UNIT else p for p in params)


def _formula(expr: str, path: str, constants: Mapping[str, float] | None) -> Formula:
    try:
        return Formula.parse(expr, constants, variables=("t",))
    except FormulaError as exc:
        raise CaseError([Problem(path, expr, f"invalid formula in t: {exc}")]) from None


def _table(params: dict[str, Any], path: str, base_dir: Path) -> TablePressure:
    where, name = f"{path}.file", params["file"]
    file = base_dir / name
    try:
        times, values, digest = _read_csv(file)
    except FileNotFoundError:
        raise CaseError([Problem(where, name, "no such file", f"looked for {file}")]) from None
    except FileRefused as exc:
        raise CaseError([Problem(where, name, str(exc), f"looked at {file}")]) from None
    except OSError as exc:
        raise CaseError([Problem(where, name, f"cannot read the table file ({exc})")]) from None
    except ValueError as exc:  # (UnicodeDecodeError too)
        raise CaseError([Problem(where, name, f"invalid table: {exc}")]) from None
    with np.errstate(all="ignore"):
        scaled = params["scale"] * values
    if not np.all(np.isfinite(scaled)):
        p = values[int(np.argmax(~np.isfinite(scaled)))]
        raise CaseError([Problem(f"{path}.scale", params["scale"], f"scale × p overflows for p = {p:g} in {name}",
                                 "expected a finite scaled pressure")])
    try:
        table = TablePressure(times, values, period=params["period"], scale=params["scale"], file=name, sha256=digest)
    except ValueError as exc:
        raise CaseError([Problem(where, name, f"invalid table: {exc}")]) from None
    expected = params["sha256"]
    if expected is not None and expected.lower() != table.sha256:
        raise CaseError([Problem(f"{path}.sha256", expected, "the file's SHA-256 differs",
                                 f"the file now has {table.sha256}")])
    return table
