"""Pressure loads P(t): inlet, outlet, external and interface pressures.

The scheme never samples a pressure at a point in time: it uses the time
average Pⁿ = (1/Δt) ∫ P dt over [tⁿ, tⁿ⁺¹] (theory §6).  Every load therefore
knows its exact integral where a closed form exists (constant, cosine pulse,
sine, piecewise-linear table) and a 5-point Gauss–Legendre rule otherwise
(formula).

A case file writes a load as a number (constant, in CGS), a number with
its unit (``"80 mmHg"``, ``"6 mL/s"``: a constant), a string (formula in
``t``) or a table ``{model = "...", ...}``; :func:`load_from_spec` turns any
of them into a :class:`PressureLoad` or raises a
:class:`~multilayer.plugin.problems.CaseError` naming the key path.  The
same kinds serve another quantity given as a function of t (a flow rate):
the caller names its unit, in which the messages speak.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar

import attrs
import numpy as np
from scipy.interpolate import CubicSpline

from multilayer.functions.formula import Formula, FormulaError
from multilayer.functions.tablefile import MAX_TABLE_TIME, FileRefused, read_csv
from multilayer.plugin import units
from multilayer.plugin.problems import (
    MISSING,
    CaseError,
    Problem,
    check_params,
    did_you_mean,
    old_model_problems,
)
from multilayer.plugin.records import MODEL, Param

#: the unit of the values of the load kinds (:data:`KINDS`): a pressure's
PRESSURE_UNIT = "dyn/cm²"


class LoadSpec(ABC):
    """The type of a plugin parameter whose value is a load as a case writes it, for :func:`load_from_spec`:
    a number, a formula in t or a table ``{model = ...}`` (``Param("flow", type=LoadSpec)``).

    >>> isinstance(2.0, LoadSpec), isinstance("sin(t)", LoadSpec), isinstance({"model": "sine"}, LoadSpec)
    (True, True, True)
    >>> isinstance(True, LoadSpec), isinstance([1.0], LoadSpec)
    (False, False)
    """

    #: what a value of this type is, in the words of a validation message
    noun: ClassVar[str] = "a number, a formula in t or a table {model = ...}"

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

    #: its name in a case file (``model = "cosine-pulse"``)
    model: ClassVar[str]

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

    def cycle(self) -> float | None:
        """The period (s) with which P repeats; None when it does not."""
        return None

    def next_breakpoint(self, t: float) -> float:
        """The first time after ``t`` where P or its slope jumps (math.inf: none); adaptive steps land on it."""
        return math.inf


@attrs.frozen
class ConstantPressure(PressureLoad):
    """P(t) = value.

    >>> ConstantPressure(3.0).average(0.0, 0.1)
    3.0
    """

    model: ClassVar[str] = "constant"
    value_: float = attrs.field(converter=float, alias="value")

    def value(self, t: Any) -> Any:
        return self.value_ + 0.0 * np.asarray(t, dtype=float)

    def integral(self, t0: float, t1: float) -> float:
        return self.value_ * (t1 - t0)

    def average(self, t0: float, t1: float) -> float:
        return self.value_

    def to_dict(self) -> dict[str, Any]:
        return {MODEL: self.model, "value": self.value_}


@attrs.frozen
class CosinePulse(PressureLoad):
    """P = amplitude/2 · (1 − cos(2πt/duration)) for 0 ≤ t ≤ duration, 0 otherwise.

    The inlet pulse of the reference scene (theory §9): amplitude = P_max.

    >>> p = CosinePulse(amplitude=2.0, duration=1.0)
    >>> float(p.value(0.5)), p.average(0.0, 1.0), p.average(1.0, 2.0)
    (2.0, 1.0, 0.0)
    """

    model: ClassVar[str] = "cosine-pulse"
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
        return {MODEL: self.model, "amplitude": self.amplitude, "duration": self.duration}

    def next_breakpoint(self, t: float) -> float:
        """The pulse's start and end (its second derivative jumps there).

        >>> p = CosinePulse(amplitude=1.0, duration=0.003)
        >>> p.next_breakpoint(-1.0), p.next_breakpoint(0.0), p.next_breakpoint(0.003)
        (0.0, 0.003, inf)
        """
        return next_after(t, (0.0, self.duration))


@attrs.frozen
class SinePressure(PressureLoad):
    """P = mean + amplitude · sin(2π·frequency·t + phase).

    >>> p = SinePressure(amplitude=1.0, frequency=2.0, mean=5.0)
    >>> round(p.average(0.0, 0.5), 12)
    5.0
    """

    model: ClassVar[str] = "sine"
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
        return {MODEL: self.model, "amplitude": self.amplitude, "frequency": self.frequency,
                "mean": self.mean, "phase": self.phase}

    def cycle(self) -> float:
        return 1.0 / self.frequency


#: how a table load runs between its rows
INTERPOLATIONS = ("linear", "cubic")


@attrs.frozen(eq=False)
class TablePressure(PressureLoad):
    """P through the points (times, values), times ``scale``: piecewise linear, or a cubic spline.

    Without a ``period`` the first and last values are held before and after
    the table.  With a ``period`` T the table is one cycle starting at its
    first time t₀ (it may span at most T; when it ends before t₀ + T the cycle
    closes back to the first value) and repeats for ever.

    ``interpolation = "cubic"``: the cubic spline through the points
    (``scipy.interpolate.CubicSpline``), periodic when the table is (P, P'
    and P'' continuous through every row and across cycles), not-a-knot
    otherwise; its integrals are the spline's, exact.

    >>> p = TablePressure(np.array([0.0, 1.0]), np.array([0.0, 2.0]), period=2.0)
    >>> float(p.value(1.5)), p.average(0.0, 2.0), p.average(0.0, 4.0)
    (1.0, 1.0, 1.0)
    >>> p.next_breakpoint(0.0), p.next_breakpoint(1.0), p.next_breakpoint(2.5)
    (1.0, 2.0, 3.0)
    >>> c = TablePressure(np.array([0.0, 1.0, 2.0, 3.0]), np.array([1.0, 2.0, 1.0, 0.0]), period=4.0,
    ...                   interpolation="cubic")
    >>> round(c.average(0.0, 4.0), 12), round(float(c.value(5.0)), 12), c.next_breakpoint(0.5)
    (1.0, 2.0, inf)
    """

    model: ClassVar[str] = "table"
    times: np.ndarray = attrs.field(converter=lambda a: np.asarray(a, dtype=float))
    values: np.ndarray = attrs.field(converter=lambda a: np.asarray(a, dtype=float))
    period: float | None = None  #: s; None: no repetition
    scale: float = attrs.field(default=1.0, converter=float)
    file: str = ""  #: the file as the case names it
    sha256: str = ""  #: of the file's bytes
    interpolation: str = "linear"  #: between the rows: one of :data:`INTERPOLATIONS`
    _spline: Any = attrs.field(init=False, default=None, repr=False)  #: the cubic spline (a PPoly), or None
    _primitive: Any = attrs.field(init=False, default=None, repr=False)  #: its antiderivative from t₀

    def __attrs_post_init__(self) -> None:
        if self.interpolation not in INTERPOLATIONS:
            raise ValueError(f"the interpolation must be one of {', '.join(INTERPOLATIONS)}")
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
        if self.interpolation == "cubic":
            object.__setattr__(self, "_spline", _spline(x, y, self.period is not None))
            object.__setattr__(self, "_primitive", self._spline.antiderivative())

    @classmethod
    def from_csv(cls, path: Path, file: str = "", period: float | None = None, scale: float = 1.0) -> TablePressure:
        """Read ``path`` (see :func:`read_table`); ``file`` is the name as the case gives it."""
        times, values, digest = read_csv(path)
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
        t = self._within(np.asarray(t, dtype=float))
        if self._spline is not None:
            return self._spline(np.clip(t, x[0], x[-1]))
        return np.interp(t, x, y)

    def cycle(self) -> float | None:
        return self.period

    def next_breakpoint(self, t: float) -> float:
        """The rows (linear: the slope jumps at each), repeated every period; a cubic table's first and last
        rows (held beyond them), a periodic cubic table none."""
        x, _ = self._knots()
        if self._spline is None:
            return next_after(t, x, self.period)
        return math.inf if self.period is not None else next_after(t, (x[0], x[-1]))

    def _antiderivative(self, t: float) -> float:
        """∫ P from the first time t₀ to t, exact for the piecewise-linear P (and the spline)."""
        x, y = self._knots()
        if self._spline is not None:
            cumulative = self._primitive(x)
        else:
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
        if self._spline is not None:
            return done + float(self._primitive(t))
        i = int(np.searchsorted(x, t, side="right")) - 1
        s, slope = t - x[i], (y[i + 1] - y[i]) / (x[i + 1] - x[i])
        return done + cumulative[i] + y[i] * s + 0.5 * slope * s * s

    def integral(self, t0: float, t1: float) -> float:
        return self._antiderivative(t1) - self._antiderivative(t0)

    def to_dict(self) -> dict[str, Any]:
        # the default interpolation is left out: a linear table's resolved case (and its hash) is what it was
        cubic = {"interpolation": self.interpolation} if self.interpolation != "linear" else {}
        return {MODEL: self.model, "file": self.file, "period": self.period, "scale": self.scale,
                "sha256": self.sha256, **cubic}


def _spline(x: np.ndarray, y: np.ndarray, periodic: bool) -> Any:
    """The cubic spline through (x, y): periodic (the first and last values must agree), or not-a-knot."""
    if periodic and y[-1] != y[0]:
        raise ValueError(f"a periodic cubic table whose last row is at t₀ + period must end on its first value "
                         f"({y[0]:g}), not {y[-1]:g}")
    return CubicSpline(x, y, bc_type="periodic" if periodic else "not-a-knot")


def next_after(t: float, points: Sequence[float], period: float | None = None) -> float:
    """The first of the increasing ``points`` after ``t``, repeated every ``period`` when given (math.inf: none).

    A point within round-off of t (1e-12 relative) is t itself: a step that landed on it goes on to the next.

    >>> next_after(0.25, [0.0, 0.5, 1.0]), next_after(1.0, [0.0, 0.5, 1.0]), next_after(2.2, [0.0, 0.5], 1.0)
    (0.5, inf, 2.5)
    """
    points = np.asarray(points, dtype=float)
    margin = 1e-12 * max(abs(t), float(points[-1] - points[0]), period or 0.0)
    if period is None:
        later = points[points > t + margin]
        return float(later[0]) if later.size else math.inf
    cycles = (t - points[0]) // period
    for k in (cycles, cycles + 1.0):
        later = points[points + k * period > t + margin]
        if later.size:
            return float(later[0] + k * period)
    return math.inf


_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(5)


@attrs.frozen
class FormulaPressure(PressureLoad):
    """P(t) given by a :class:`~multilayer.functions.formula.Formula` in ``t``.

    Its step average uses 5-point Gauss–Legendre (exact for polynomials of degree ≤ 9).

    >>> round(FormulaPressure(Formula.parse("3*t**2", variables=("t",))).average(0.0, 1.0), 12)
    1.0
    """

    model: ClassVar[str] = "formula"
    formula: Formula

    def value(self, t: Any) -> Any:
        return self.formula(t=t)

    def integral(self, t0: float, t1: float) -> float:
        half = 0.5 * (t1 - t0)
        return half * float(_GAUSS_W @ self.formula(t=t0 + half * (_GAUSS_X + 1.0)))

    def to_dict(self) -> dict[str, Any]:
        return {MODEL: self.model, "expr": str(self.formula)}


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
        Param("interpolation", type=str, default="linear", choices=INTERPOLATIONS,
              doc="between the rows: linear, or a cubic spline (periodic when the table is)"),
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
    {'model': 'constant', 'value': 0.0}
    >>> round(load_from_spec("1e4*t", "loads.inlet").average(0.0, 2.0), 9)
    10000.0
    >>> load_from_spec("10 mmHg", "loads.inlet").to_dict()
    {'model': 'constant', 'value': 13332.2387415}
    >>> load_from_spec({"model": "cosine-pulse", "amplitude": 1.3333e4, "duration": 0.003}, "loads.inlet").model
    'cosine-pulse'
    >>> load_from_spec({"model": "cosine-puls", "amplitude": 1.0}, "loads.inlet")
    Traceback (most recent call last):
    ...
    multilayer.plugin.problems.CaseError: loads.inlet.model = 'cosine-puls': no such pressure load; did you mean 'cosine-pulse'?
    >>> load_from_spec({"kind": "table", "file": "aortic.csv"}, "loads.inlet")
    Traceback (most recent call last):
    ...
    multilayer.plugin.problems.CaseError: loads.inlet.kind = 'table': plugins are chosen by 'model', not 'kind'; write model = "table"
    >>> load_from_spec({"model": "sine", "amplitude": "2"}, "loads.inlet.flow", quantity="flow rate", unit="cm²/s")
    Traceback (most recent call last):
    ...
    multilayer.plugin.problems.CaseError: loads.inlet.flow.amplitude = '2': expected a number (cm²/s)
    loads.inlet.flow.frequency: missing; expected a number > 0.0 (Hz)
    """
    if isinstance(spec, int | float) and not isinstance(spec, bool):
        if not math.isfinite(spec):
            raise CaseError([Problem(path, spec, f"expected a finite {quantity} ({unit})")])
        unlikely = units.implausible(path.rpartition(".")[2], unit, float(spec))
        if unlikely:
            units.note(f"{path} = {spec!r}: {unlikely}")
        return ConstantPressure(spec)
    if isinstance(spec, str):
        try:
            value = units.to_cgs(spec, unit)  # "80 mmHg": a constant with its unit
        except units.UnitError as exc:
            raise CaseError([Problem(path, spec, str(exc))]) from None
        return FormulaPressure(_formula(spec, path, constants)) if value is None else ConstantPressure(value)
    if not isinstance(spec, Mapping):
        raise CaseError([Problem(path, spec, "expected a number, a formula in t or a table {model = ...}")])
    if old := old_model_problems(spec, path):
        raise CaseError(old)
    name = spec.get(MODEL, MISSING)
    if not isinstance(name, str) or name not in KINDS:
        expected = f"no such {quantity} load" if name is not MISSING else "missing; expected the name of a load"
        hint = did_you_mean(name, KINDS) if isinstance(name, str) else ""
        raise CaseError([Problem(f"{path}.{MODEL}", name, expected, hint or "available: " + ", ".join(KINDS))])
    params, problems = check_params(spec, in_unit(KINDS[name], unit), path, extra=(MODEL,))
    if problems:
        raise CaseError(problems)
    if name == "constant":
        return ConstantPressure(params["value"])
    if name == "cosine-pulse":
        return CosinePulse(**params)
    if name == "sine":
        return SinePressure(**params)
    if name == "formula":
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
        times, values, digest = read_csv(file)
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
        table = TablePressure(times, values, period=params["period"], scale=params["scale"], file=name, sha256=digest,
                              interpolation=params["interpolation"])
    except ValueError as exc:
        raise CaseError([Problem(where, name, f"invalid table: {exc}")]) from None
    expected = params["sha256"]
    if expected is not None and expected.lower() != table.sha256:
        raise CaseError([Problem(f"{path}.sha256", expected, "the file's SHA-256 differs",
                                 f"the file now has {table.sha256}")])
    return table
