"""What is wrong with a case, in the user's words: key path, value, what was expected.

A :class:`CaseError` carries every :class:`Problem` found in one pass.  The
parameter checker here serves both the core sections of a case file and the
parameters a plugin declares with :class:`multilayer.plugin.records.Param`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

import attrs

from multilayer.plugin import units
from multilayer.plugin.records import MODEL, OLD_MODEL, Param, old_model_text
from multilayer.plugin.registry import nearest

#: The value of a key that is not there.
MISSING: Any = attrs.make_class("Missing", [], repr_ns=None)()


def show(value: Any) -> str:
    """A value as the user wrote it, shortened.

    >>> show("koiter"), show(-3.0), show(True), show(list(range(40)))[-8:]
    ("'koiter'", '-3.0', 'true', '0, 21...')
    """
    if isinstance(value, bool):
        return "true" if value else "false"
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


@attrs.frozen
class Problem:
    """One mistake in a case.

    Parameters
    ----------
    path : str
        Key path in the case file, e.g. ``layers[1].young``.
    value : object
        The value found there, or :data:`MISSING`.
    expected : str
        What is wrong, phrased for the user (``"expected a number > 0"``).
    hint : str
        Optional advice, e.g. ``"did you mean 'koiter-shell'?"``.

    Examples
    --------
    >>> print(Problem("layers[1].young", -3.0, "expected a number > 0"))
    layers[1].young = -3.0: expected a number > 0
    >>> print(Problem("layers[0].model", "koiter", "no such layer plugin", "did you mean 'koiter-shell'?"))
    layers[0].model = 'koiter': no such layer plugin; did you mean 'koiter-shell'?
    """

    path: str
    value: Any
    expected: str
    hint: str = ""

    def __str__(self) -> str:
        head = self.path if self.value is MISSING else f"{self.path} = {show(self.value)}"
        return f"{head}: {self.expected}" + (f"; {self.hint}" if self.hint else "")


class CaseError(Exception):
    """An invalid case: one line per :class:`Problem`."""

    def __init__(self, problems: Iterable[Problem]):
        self.problems = list(problems)
        super().__init__("\n".join(str(p) for p in self.problems))


def old_model_problems(table: Any, path: str) -> list[Problem]:
    """The old key ``kind`` in ``table``, a table at ``path`` that names a plugin: one problem at ``path.kind``.

    >>> print(*old_model_problems({"kind": "flow-rate", "flow": 6.0}, "loads.inlet"))
    loads.inlet.kind = 'flow-rate': plugins are chosen by 'model', not 'kind'; write model = "flow-rate"
    >>> old_model_problems({"model": "flow-rate"}, "loads.inlet"), old_model_problems(6.0, "loads.inlet")
    ([], [])
    """
    if not isinstance(table, Mapping) or OLD_MODEL not in table:
        return []
    return [Problem(f"{path}.{OLD_MODEL}", table[OLD_MODEL], *old_model_text(table))]


def did_you_mean(name: str, candidates: Iterable[str]) -> str:
    hint = nearest(name, candidates)
    return f"did you mean {hint!r}?" if hint else ""


def describe(param: Param) -> str:
    """What a parameter accepts, in words.

    >>> describe(Param("poisson", gt=-1.0, lt=0.5))
    'a number > -1.0 and < 0.5'
    >>> describe(Param("order", type=int, choices=(1, 2)))
    'one of 1, 2'
    >>> describe(Param("young", unit="dyn/cm²", gt=0)), describe(Param("poisson", unit="1", lt=0.5))
    ('a number > 0 (dyn/cm²)', 'a number < 0.5')
    """
    if param.choices is not None:
        return "one of " + ", ".join(show(c) for c in param.choices)
    if param.plugin is not None:
        return f"the name of a {param.plugin} plugin, or a table {{{MODEL} = name, ...}}"
    noun = {float: "a number", int: "an integer", str: "a string", bool: "true or false"}.get(
        param.type, getattr(param.type, "noun", param.type.__name__)  # a type may say what it is
    )
    bounds = param.bounds_text()
    unit = f" ({param.unit})" if param.unit and param.unit != "1" else ""
    return f"{noun} {bounds}{unit}" if bounds else f"{noun}{unit}"


def check_value(param: Param, value: Any) -> tuple[Any, bool]:
    """``(converted value, ok)``: ints become floats for a float parameter; bools are no numbers.  A parameter
    that names a plugin takes a name or a table with a ``model`` (the validator looks the plugin up)."""
    if param.plugin is not None:
        return value, isinstance(value, str) or (isinstance(value, Mapping) and isinstance(value.get(MODEL), str))
    if param.type is float:
        ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        value = float(value) if ok else value
    elif param.type is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    else:
        ok = isinstance(value, param.type)
    if not ok:
        return value, False
    if param.choices is not None and value not in param.choices:
        return value, False
    limits = (
        (param.gt, lambda v, b: v > b),
        (param.ge, lambda v, b: v >= b),
        (param.lt, lambda v, b: v < b),
        (param.le, lambda v, b: v <= b),
    )
    return value, all(b is None or test(value, b) for b, test in limits)


def check_params(
    values: Any, schema: Iterable[Param], path: str, extra: Iterable[str] = ()
) -> tuple[dict[str, Any], list[Problem]]:
    """Check a table of parameters against ``schema``; fill in defaults.

    Keys in ``extra`` are allowed and left to the caller.  Returns the
    checked values (every schema key, defaults included, in schema order)
    and the problems found.  A number parameter may be given with its unit
    (``"80 mmHg"``): it is converted to the parameter's CGS ``unit``
    (:func:`multilayer.plugin.units.to_cgs`; another dimension is a
    problem).  A plain number implausible in that unit is noted
    (:func:`multilayer.plugin.units.note`) for the validation collecting.

    >>> schema = (Param("density", gt=0), Param("thickness", gt=0, default=0.1))
    >>> check_params({"density": 1}, schema, "layers[0]")
    ({'density': 1.0, 'thickness': 0.1}, [])
    >>> print(*check_params({"densty": 1}, schema, "layers[0]")[1], sep="\\n")
    layers[0].densty = 1: unknown key; did you mean 'density'?
    layers[0].density: missing; expected a number > 0
    >>> check_params({"thickness": "50 µm"}, (Param("thickness", unit="cm", gt=0),), "layers[0]")[0]
    {'thickness': 0.005}
    >>> print(*check_params({"thickness": "80 mmHg"}, (Param("thickness", unit="cm", gt=0),), "layers[0]")[1])
    layers[0].thickness = '80 mmHg': 80 mmHg is a pressure; expected a length (cm), like '0.3 cm'
    """
    schema = tuple(schema)
    if not isinstance(values, Mapping):
        return {}, [Problem(path, values, "expected a table")]
    known = [p.name for p in schema] + list(extra)
    problems = [
        Problem(f"{path}.{key}", value, "unknown key", did_you_mean(key, known))
        for key, value in values.items()
        if key not in known
    ]
    checked: dict[str, Any] = {}
    for param in schema:
        where = f"{path}.{param.name}"
        if param.name not in values:
            if param.required:
                problems.append(Problem(where, MISSING, f"missing; expected {describe(param)}"))
            else:
                checked[param.name] = param.default
            continue
        raw = values[param.name]
        if (raw is None or (raw == "none" and param.type is not str)) and param.default is None:
            checked[param.name] = None  # resolved JSON writes an unset option as null; "none" (--set, --vary) unsets
            continue
        given = raw
        if isinstance(raw, str) and param.type is float:  # a value with its unit ("80 mmHg"), in the key's CGS unit
            try:
                converted = units.to_cgs(raw, param.unit)
            except units.UnitError as exc:
                problems.append(Problem(where, raw, str(exc)))
                continue
            given = raw if converted is None else converted
        value, ok = check_value(param, given)
        if ok:
            checked[param.name] = value
            if given is raw and param.type is float:
                unlikely = units.implausible(param.name, param.unit, value)
                if unlikely:
                    units.note(f"{where} = {show(raw)}: {unlikely}")
        else:
            hint = did_you_mean(raw, map(str, param.choices)) if param.choices and isinstance(raw, str) else ""
            if given is not raw:
                hint = f"{raw} = {given:.6g} {param.unit}"
            problems.append(Problem(where, raw, f"expected {describe(param)}", hint))
    return checked, problems
