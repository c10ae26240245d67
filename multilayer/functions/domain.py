"""A formula judged on its domain: finite and real wherever a run may evaluate it.

A formula is data, so it is judged when the case is validated, not when a
run meets it: :func:`defect` evaluates it on a grid over the ranges of its
variables (end points included) and names the first point where it is not a
finite real number, and why (a division by zero, an overflow, not a real
number).  The grid is modest (:data:`POINTS`), so a singularity between grid
points can still slip through; the runner then stops on the non-finite
value it meets, as for any other.
"""

from __future__ import annotations

from collections.abc import Mapping

import attrs
import numpy as np

from multilayer.functions.formula import Formula
from multilayer.plugin.problems import Problem

#: Grid points per variable, by the number of variables the domain has.
POINTS = {1: 257, 2: 65, 3: 17}

#: What numpy's floating-point flag means, in the user's words.
CAUSES = {
    "divide by zero": "a division by zero (or log of 0)",
    "overflow": "an overflow (beyond the largest float, about 1.8e308)",
    "invalid value": "not a real number (e.g. sqrt or log of a negative number, 0/0, inf - inf)",
}


@attrs.frozen
class Domain:
    """The ranges of a formula's variables: ``{"t": (0.0, 0.012)}``, ``{"z": (0, 6), "r": (0.5, 0.6)}``.

    Examples
    --------
    >>> d = Domain({"z": (0.0, 6.0), "r": (0.5, 0.5)})
    >>> str(d), sorted(d.grid()), d.grid()["z"].shape
    ('z in [0, 6], r = 0.5', ['r', 'z'], (65, 1))
    """

    ranges: Mapping[str, tuple[float, float]] = attrs.field(converter=lambda r: dict(r))

    def grid(self) -> dict[str, np.ndarray]:
        """Each variable on its own axis of an open grid (end points included), broadcastable together."""
        n = POINTS.get(len(self.ranges), 9)
        out = {}
        for axis, (name, (lo, hi)) in enumerate(self.ranges.items()):
            values = np.linspace(lo, hi, n) if hi > lo else np.array([float(lo)])
            shape = [1] * len(self.ranges)
            shape[axis] = values.size
            out[name] = values.reshape(shape)
        return out

    def __str__(self) -> str:
        return ", ".join(f"{name} = {lo:g}" if hi <= lo else f"{name} in [{lo:g}, {hi:g}]"
                         for name, (lo, hi) in self.ranges.items())


def _flags(formula: Formula, point: Mapping[str, float]) -> list[str]:
    """The floating-point flags numpy raises evaluating ``formula`` at one point."""
    raised: list[str] = []
    with np.errstate(divide="call", over="call", invalid="call", under="ignore",
                     call=lambda kind, flag: raised.append(kind)):
        formula(**point)
    return raised


def defect(formula: Formula, domain: Domain) -> str | None:
    """Why ``formula`` is not a finite real number somewhere on ``domain``, or None when it is one everywhere.

    Examples
    --------
    >>> t = Domain({"t": (0.0, 0.01)})
    >>> defect(Formula.parse("1e4*sin(t)"), t) is None
    True
    >>> defect(Formula.parse("1/(t-t)"), t)
    'gives inf at t = 0: a division by zero (or log of 0)'
    >>> defect(Formula.parse("exp(1000*t/0.01)"), t)
    'gives inf at t = 0.00710938: an overflow (beyond the largest float, about 1.8e308)'
    >>> defect(Formula.parse("sqrt(t - 0.005)"), t)
    'gives nan at t = 0: not a real number (e.g. sqrt or log of a negative number, 0/0, inf - inf)'
    """
    grid = domain.grid()
    with np.errstate(all="ignore"):
        values = formula(**grid)
    bad = np.argwhere(~np.isfinite(values))
    if bad.size == 0:
        return None
    index = tuple(bad[0])
    point = {name: float(np.broadcast_to(v, values.shape)[index]) for name, v in grid.items()}
    flags = _flags(formula, point)
    cause = next((CAUSES[f] for f in CAUSES if f in flags), "not finite")
    where = ", ".join(f"{name} = {value:g}" for name, value in point.items())
    return f"gives {values[index]:g} at {where}: {cause}"


def judge(formula: Formula, path: str, domain: Domain) -> Problem | None:
    """The problem at ``path`` when ``formula`` is not a finite real number somewhere on ``domain`` (else None).

    >>> print(judge(Formula.parse("1/(t-t)"), "loads.inlet", Domain({"t": (0.0, 1.0)})))
    loads.inlet = '1/(t-t)': gives inf at t = 0: a division by zero (or log of 0); expected a finite real value for every t in [0, 1]
    """
    reason = defect(formula, domain)
    if reason is None:
        return None
    return Problem(path, str(formula), f"{reason}; expected a finite real value for every {domain}")
