"""Grids of runs over case keys: the planning pieces ``study``, ``stability`` and ``sweep`` share.

An *axis* is a list of points; a *point* is a tuple of :class:`Setting`
(one for ``--vary KEY=A,B`` or a ``[sweep] grid`` key, several for keys
varied together, ``[sweep] zip``).  A grid is the product of its axes
(:func:`combinations`), each combination one run: the case file with the
settings' overrides applied after ``--set``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from typing import Any

import attrs

from multilayer.case.keys import key_steps, parse_vary
from multilayer.plugin.problems import CaseError, Problem, did_you_mean


@attrs.frozen
class Setting:
    """One value of one axis of the grid: ``key=value`` in labels and folders, and the override it applies.

    For ``--vary`` the override is ``key=value`` itself; another command
    may name a value by one quantity and realise it by another (the
    stability map's ``ratio=0.01`` sets ``layers[0].density``).
    """

    key: str
    value: str
    override: str


Point = tuple[Setting, ...]


def vary_axis(key: str, values: Sequence[str]) -> list[Setting]:
    """The settings of ``--vary KEY=A,B,...``: each value applied as ``KEY=value``.

    >>> vary_axis("time.dt", ["1e-4", "5e-5"])[1]
    Setting(key='time.dt', value='5e-5', override='time.dt=5e-5')
    """
    return [Setting(key, v, f"{key}={v}") for v in values]


def zip_axis(columns: Sequence[tuple[str, Sequence[str]]]) -> list[Point]:
    """Keys varied together: the i-th point sets the i-th value of every key.

    >>> [tuple(s.override for s in p) for p in zip_axis([("time.dt", ["1e-4", "5e-5"]), ("mesh.nz", ["12", "24"])])]
    [('time.dt=1e-4', 'mesh.nz=12'), ('time.dt=5e-5', 'mesh.nz=24')]
    """
    lengths = {len(values) for _, values in columns}
    if len(lengths) > 1:
        raise ValueError(f"keys varied together need as many values each; got {sorted(lengths)}")
    return list(zip(*(vary_axis(key, values) for key, values in columns)))


def combinations(axes: Sequence[Sequence[Point]]) -> list[Point]:
    """Every combination of one point per axis, the first axis slowest; each flattened to its settings.

    >>> dt = [(s,) for s in vary_axis("time.dt", ["1e-4", "5e-5"])]
    >>> [tuple(s.value for s in p) for p in combinations([dt, [(Setting("mesh.nz", "12", "mesh.nz=12"),)]])]
    [('1e-4', '12'), ('5e-5', '12')]
    >>> combinations([])
    [()]
    """
    return [tuple(s for point in combo for s in point) for combo in itertools.product(*axes)]


def parse_varies(texts: Sequence[str], reserved: Mapping[str, str] | None = None) -> list[tuple[str, list[str]]]:
    """Every ``--vary KEY=A,B,...`` (read like compare's); CaseError listing every malformed one.

    ``reserved`` maps a first key step another option owns to the message
    given when it is varied (``{"coupler": "the coupler is chosen with
    --couplers"}``).

    >>> parse_varies(["time.dt=1e-4,5e-5", "mesh.nz=12,24"])
    [('time.dt', ['1e-4', '5e-5']), ('mesh.nz', ['12', '24'])]
    >>> parse_varies(["time.dt=1,2", "time.dt=3,4"])
    Traceback (most recent call last):
    ...
    multilayer.plugin.problems.CaseError: --vary = 'time.dt=3,4': time.dt is already varied
    """
    out: list[tuple[str, list[str]]] = []
    problems: list[Problem] = []
    for text in texts:
        try:
            key, values = parse_vary(text)
        except CaseError as exc:
            problems += exc.problems
            continue
        first = key_steps(key)[0]
        if reserved and first in reserved:
            problems.append(Problem("--vary", text, reserved[first]))
        elif key in (k for k, _ in out):
            problems.append(Problem("--vary", text, f"{key} is already varied"))
        else:
            out.append((key, values))
    if problems:
        raise CaseError(problems)
    return out


def toml_text(value: Any) -> str:
    """A TOML value as the text a ``--set`` reads back to it (inline tables and arrays too).

    >>> toml_text(5e-5), toml_text("koiter-shell"), toml_text(True), toml_text([1, 2.5])
    ('5e-05', '"koiter-shell"', 'true', '[1, 2.5]')
    >>> toml_text({"model": "wave-membrane", "tension": 2e4})
    '{model = "wave-membrane", tension = 20000.0}'
    """
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        return ("inf" if value > 0 else "-inf") if math.isinf(value) else repr(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{_bare_key(k)} = {toml_text(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_text(v) for v in value) + "]"
    raise TypeError(f"not a TOML value: {value!r}")


def _bare_key(key: str) -> str:
    return key if key and all(c.isalnum() or c in "_-" for c in key) else toml_text(key)


# -- the [sweep] table of a case file ---------------------------------------------

SWEEP_KEYS = ("grid", "zip")


@attrs.frozen
class SweepTable:
    """A case file's ``[sweep]``: ``grid`` keys (the product of their values) and ``zip`` groups.

    Values are TOML values as the file has them (numbers, strings, inline
    tables...); :meth:`axes` turns them into override texts.
    """

    grid: tuple[tuple[str, tuple[Any, ...]], ...] = ()
    zips: tuple[tuple[tuple[str, tuple[Any, ...]], ...], ...] = ()

    @property
    def keys(self) -> list[str]:
        """Every key the table varies, grid keys first."""
        return [k for k, _ in self.grid] + [k for group in self.zips for k, _ in group]

    def axes(self) -> list[list[Point]]:
        """One axis per grid key, then one per zip group; each value as :func:`toml_text` of it."""
        axes: list[list[Point]] = [[(s,) for s in vary_axis(key, [toml_text(v) for v in values])]
                                   for key, values in self.grid]
        axes += [zip_axis([(key, [toml_text(v) for v in values]) for key, values in group]) for group in self.zips]
        return axes

    @property
    def size(self) -> int:
        """How many runs the grid has."""
        return math.prod([len(v) for _, v in self.grid] + [len(group[0][1]) for group in self.zips])


def _values(path: str, values: Any, problems: list[Problem]) -> tuple[Any, ...] | None:
    if not isinstance(values, list):
        problems.append(Problem(path, values, "expected a list of the values to run"))
        return None
    if not values:
        problems.append(Problem(path, values, "expected one or more values"))
        return None
    return tuple(values)


def _columns(path: str, table: Any, problems: list[Problem]) -> list[tuple[str, tuple[Any, ...]]]:
    """The ``"key" = [values]`` of one table under ``[sweep]``."""
    if not isinstance(table, Mapping):
        problems.append(Problem(path, table, 'expected a table of "key.path" = [values]'))
        return []
    columns = []
    for key, values in table.items():
        where = f'{path}."{key}"'
        if not key_steps(key):
            problems.append(Problem(where, values, "not a key path; expected a key like time.dt or layers[0].young"))
            continue
        if key_steps(key)[0] == "sweep":
            problems.append(Problem(where, values, "a sweep cannot vary itself"))
            continue
        checked = _values(where, values, problems)
        if checked is not None:
            columns.append((key, checked))
    return columns


def sweep_table(value: Any) -> tuple[SweepTable | None, list[Problem]]:
    """Read and check a case file's ``[sweep]`` table: (the table, the problems with their key paths).

    ``grid`` is a table of ``"key.path" = [values]``, run as the product of
    all lists; ``zip`` a table of lists of one length (the i-th run of the
    group takes the i-th value of each), or an array of such tables (one
    axis each).  A key may appear once.

    Examples
    --------
    >>> table, problems = sweep_table({"grid": {"time.dt": [1e-4, 5e-5], "layers[0].young": [5e5, 1e6]}})
    >>> table.size, table.keys, problems
    (4, ['time.dt', 'layers[0].young'], [])
    >>> print(*sweep_table({"gird": {}})[1])
    sweep.gird = {}: unknown key; did you mean 'grid'?
    >>> print(*sweep_table({"zip": {"time.dt": [1e-4, 5e-5], "time.end": [1e-3]}})[1])
    sweep.zip = {'time.dt': [0.0001, 5e-05], 'time.end': [0.001]}: expected lists of one length (they are varied together); got 2, 1
    """
    problems: list[Problem] = []
    if not isinstance(value, Mapping):
        return None, [Problem("sweep", value, "expected a table with grid = {...} and/or zip = {...}")]
    problems += [Problem(f"sweep.{k}", v, "unknown key", did_you_mean(k, SWEEP_KEYS))
                 for k, v in value.items() if k not in SWEEP_KEYS]
    grid = _columns("sweep.grid", value.get("grid", {}), problems)
    groups = value.get("zip", [])
    groups = [groups] if isinstance(groups, Mapping) else groups
    zips = []
    if not isinstance(groups, list):
        problems.append(Problem("sweep.zip", groups, "expected a table of lists, or an array of such tables"))
        groups = []
    for i, group in enumerate(groups):
        path = "sweep.zip" if isinstance(value.get("zip"), Mapping) else f"sweep.zip[{i}]"
        columns = _columns(path, group, problems)
        lengths = [len(v) for _, v in columns]
        if len(set(lengths)) > 1:
            problems.append(Problem(path, group, "expected lists of one length (they are varied together); got "
                                    + ", ".join(map(str, lengths))))
        elif columns:
            zips.append(tuple(columns))
    table = SweepTable(tuple(grid), tuple(zips))
    seen: set[str] = set()
    for key in table.keys:
        if key in seen:
            problems.append(Problem("sweep", key, "this key is varied twice (in grid and zip, or two zip groups)"))
        seen.add(key)
    if not problems and not table.keys:
        problems.append(Problem("sweep", dict(value), "varies no key; expected grid = {\"key\" = [values]} or zip"))
    return (None if problems else table), problems
