"""Units a person reads and types: the CGS the scheme computes in, the clinic's mmHg and mL/s.

Case files and the scheme are in CGS (cm, g, s; pressures in dyn/cm²).  A
case-file value may also carry its unit — ``"80 mmHg"``, ``"6 mL/s"``,
``"400 kPa"``, ``"0.3 cm"``, ``"1.06 g/cm^3"`` — which :func:`to_cgs`
converts with pint into the CGS unit the parameter declares
(:class:`~multilayer.plugin.records.Param` ``unit``), refusing a value of
another dimension (:class:`UnitError`).  A plain number stays CGS; one
implausible for its key (a Young's modulus of 400 dyn/cm², a density of
1060 g/cm³) gets a note naming the unit it was likely meant in
(:func:`implausible`), which validation collects (:func:`collecting`) and
``multilayer validate`` / ``run`` print.

pint is imported only when a value carries a unit: plain cases validate
without it.
"""

from __future__ import annotations

import contextlib
import functools
import math
import re
from collections.abc import Iterator
from contextvars import ContextVar
from typing import Any

#: dyn/cm² in one mmHg (the conventional millimetre of mercury, 133.322387415 Pa)
MMHG = 1333.22387415
#: the pressure a person reads: mmHg
PRESSURE_UNIT = "mmHg"

_SUPERSCRIPTS = str.maketrans({"²": "**2", "³": "**3", "⁴": "**4", "⁵": "**5", "·": "*", "⁻": "-", "¹": "1"})
#: a number, then a unit: the unit starts with a letter (or µ, °, %), so a formula like "2*t" is no quantity
_QUANTITY = re.compile(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)(?![\d.]|[eE][-+]?\d)\s*"
                       r"([A-Za-zµμ°%].*?)\s*$")
#: the dimensions a message names, by a CGS unit of each
_DIMENSIONS = (
    ("cm", "a length"), ("s", "a time"), ("Hz", "a frequency"), ("g/cm**3", "a density"),
    ("dyn/cm**2", "a pressure"), ("P", "a dynamic viscosity"), ("cm**3/s", "a flow rate"),
    ("cm**2/s", "a flow rate per unit depth"), ("dyn*s/cm**5", "a resistance"),
    ("dyn*s/cm**4", "a resistance per unit depth"), ("cm**5/dyn", "a compliance"),
    ("cm**4/dyn", "a compliance per unit depth"), ("dyn/cm", "a tension"), ("dyn/cm**3", "a stiffness per area"),
    ("g", "a mass"), ("", "a pure number"),
)
#: what a unit looks like, by dimension, for messages
_EXAMPLES = {"a length": "0.3 cm", "a time": "2 ms", "a frequency": "1.2 Hz", "a density": "1.06 g/cm^3",
             "a pressure": "80 mmHg", "a dynamic viscosity": "3.5 cP", "a flow rate": "6 mL/s",
             "a resistance": "1.8 mmHg*s/mL", "a compliance": "0.04 mL/mmHg"}


class UnitError(ValueError):
    """A value whose unit is unknown or of the wrong dimension for its key; the message is one line."""


@functools.cache
def registry() -> Any:
    """pint's unit registry (imported on first use: a case without units never loads pint)."""
    import pint

    return pint.UnitRegistry()


def targets(unit: str) -> tuple[str, ...]:
    """The CGS units a :class:`~multilayer.plugin.records.Param` ``unit`` text stands for, as pint reads them;
    () when it names no physical unit (a count, ``"1"``, a fraction of R).

    >>> targets("dyn/cm²"), targets("P = g/(cm·s)"), targets("1"), targets("R")
    (('dyn/cm**2',), ('g/(cm*s)',), (), ())
    >>> targets("dyn·s/cm⁴ per unit depth (planar), dyn·s/cm⁵ (tube)")
    ('dyn*s/cm**4', 'dyn*s/cm**5')
    """
    out = []
    for part in unit.split(","):
        text = re.sub(r"\((planar|tube)\)|per unit depth", "", part).split("=")[-1].strip()
        if text and text not in ("1", "R"):
            out.append(text.translate(_SUPERSCRIPTS))
    return tuple(out)


def quantity(text: str) -> tuple[float, str] | None:
    """(number, unit) of a value written as a number with a unit, or None.

    >>> quantity("80 mmHg"), quantity("1.06 g/cm^3"), quantity("2*t"), quantity("3"), quantity("1e4*t")
    ((80.0, 'mmHg'), (1.06, 'g/cm^3'), None, None, None)
    >>> quantity("4e5 dyn/cm²"), quantity("4e5dyn")
    ((400000.0, 'dyn/cm**2'), (400000.0, 'dyn'))
    """
    match = _QUANTITY.fullmatch(text)
    return (float(match.group(1)), match.group(2).translate(_SUPERSCRIPTS)) if match else None


def dimension(unit: str) -> str:
    """What a unit measures, in words (``"a pressure"``), or its dimensions as pint writes them.

    >>> dimension("mmHg"), dimension("mL/s"), dimension("kg/m**3")
    ('a pressure', 'a flow rate', 'a density')
    """
    ureg = registry()
    found = ureg.parse_units(unit).dimensionality if unit else ureg.dimensionless.dimensionality
    for reference, name in _DIMENSIONS:
        own = ureg.parse_units(reference).dimensionality if reference else ureg.dimensionless.dimensionality
        if own == found:
            return name
    return f"a quantity of dimension {found}"


def to_cgs(text: str, unit: str) -> float | None:
    """The value of ``text`` ("80 mmHg") in the CGS unit ``unit`` of its key, to 15 significant digits; None when
    ``text`` is not a number with a unit (a formula, a word).

    Raises
    ------
    UnitError
        When the unit is unknown to pint or measures something else than ``unit``: one line that says what it
        measures and what was expected.

    Examples
    --------
    >>> round(to_cgs("80 mmHg", "dyn/cm²"), 3), to_cgs("6 mL/s", "cm²/s per unit depth (planar), cm³/s (tube)")
    (106657.91, 6.0)
    >>> to_cgs("50 µm", "cm"), to_cgs("sin(t)", "dyn/cm²")
    (0.005, None)
    >>> to_cgs("80 mmHg", "cm")
    Traceback (most recent call last):
    ...
    multilayer.plugin.units.UnitError: 80 mmHg is a pressure; expected a length (cm), like '0.3 cm'
    """
    found = quantity(text)
    goals = targets(unit)
    if found is None or not goals:
        return None
    number, written = found
    ureg = registry()
    try:
        value = ureg.Quantity(number, written)
    except Exception as exc:  # pint's errors for a name it does not know, or a malformed expression
        raise UnitError(f"{written!r} is no unit pint knows ({type(exc).__name__}); expected {_expected(goals)}") \
            from None
    for goal in goals:
        if value.dimensionality == ureg.parse_units(goal).dimensionality:
            # to 15 digits: the factors' last-bit noise (50 µm = 0.004999999999999999 cm) would reach the digest
            return float(f"{value.to(goal).magnitude:.15g}")
    raise UnitError(f"{number:g} {written} is {dimension(written)}; expected {_expected(goals)}")


def _expected(goals: tuple[str, ...]) -> str:
    names = [dimension(g) for g in goals]
    shown = " or ".join(f"{name} ({unit})" for name, unit in zip(names, _display(goals)))
    example = next((_EXAMPLES[n] for n in names if n in _EXAMPLES), None)
    return shown + (f", like {example!r}" if example else "")


def _display(goals: tuple[str, ...]) -> list[str]:
    back = {v: k for k, v in (("²", "**2"), ("³", "**3"), ("⁴", "**4"), ("⁵", "**5"), ("·", "*"))}
    out = []
    for goal in goals:
        for power, sign in back.items():
            goal = goal.replace(power, sign)
        out.append(goal)
    return out


# -- plain numbers implausible in CGS -------------------------------------------------------------------------

#: (the keys' CGS unit, their names (empty: any), the plausible range of |value|, a typical value, the likely
#: units with their size in the CGS unit, the CGS unit as a message writes it)
_PLAUSIBLE = (
    ("dyn/cm²", ("young", "lame_mu", "viscous_young", "shear_modulus", "bulk_modulus", "fibre_modulus"),
     (1e3, math.inf), 1e6, (("kPa", 1e4), ("MPa", 1e7)), "dyn/cm²"),
    ("dyn/cm²", (), (1.0, math.inf), 1.3e4, (("mmHg", MMHG), ("kPa", 1e4)), "dyn/cm²"),
    ("g/cm³", (), (0.0, 100.0), 1.0, (("kg/m³", 1e-3),), "g/cm³"),
    ("P = g/(cm·s)", (), (0.0, 1.0), 0.035, (("cP", 1e-2),), "P"),
    ("cm", ("length", "radius", "thickness"), (0.0, 100.0), 0.5, (("mm", 0.1), ("µm", 1e-4)), "cm"),
    ("dyn·s/cm⁴ per unit depth (planar), dyn·s/cm⁵ (tube)", (), (10.0, math.inf), 1e4, (("mmHg·s/mL", MMHG),),
     "dyn·s/cm⁵"),
    ("cm⁴/dyn per unit depth (planar), cm⁵/dyn (tube)", (), (0.0, 1e-2), 3e-5, (("mL/mmHg", 1 / MMHG),), "cm⁵/dyn"),
)


def implausible(name: str, unit: str, value: float) -> str | None:
    """Why the plain number ``value`` of key ``name`` (in its CGS ``unit``) looks like another unit, or None.

    Zero is never implausible.  Of the likely units the one that brings the value nearest a typical one is named.

    >>> implausible("young", "dyn/cm²", 400.0)
    'did you mean 400 kPa = 4e+06 dyn/cm²? (a plain number is read in dyn/cm²)'
    >>> implausible("density", "g/cm³", 1060.0)
    'did you mean 1060 kg/m³ = 1.06 g/cm³? (a plain number is read in g/cm³)'
    >>> implausible("amplitude", "dyn/cm²", 0.5), implausible("young", "dyn/cm²", 2e6), implausible("value", "dyn/cm²", 0.0)
    ('did you mean 0.5 kPa = 5000 dyn/cm²? (a plain number is read in dyn/cm²)', None, None)
    """
    if not value or not math.isfinite(value):
        return None
    for cgs, names, (low, high), typical, candidates, shown_cgs in _PLAUSIBLE:
        if unit != cgs or (names and name not in names):
            continue
        if low <= abs(value) <= high:
            return None
        shown, factor = min(candidates, key=lambda c: abs(math.log10(abs(value) * c[1] / typical)))
        return (f"did you mean {value:g} {shown} = {value * factor:.4g} {shown_cgs}? "
                f"(a plain number is read in {shown_cgs})")
    return None


_NOTES: ContextVar[list[str] | None] = ContextVar("multilayer_unit_notes", default=None)


def note(message: str) -> None:
    """Keep ``message`` for the validation that is collecting (:func:`collecting`); none collects: nothing."""
    found = _NOTES.get()
    if found is not None and message not in found:
        found.append(message)


@contextlib.contextmanager
def collecting() -> Iterator[list[str]]:
    """The notes of everything validated inside, in order, each once (its own list per thread and task)."""
    found: list[str] = []
    token = _NOTES.set(found)
    try:
        yield found
    finally:
        _NOTES.reset(token)
