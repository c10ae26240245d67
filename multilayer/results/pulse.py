"""The pulse-wave velocity of a run's series, as a clinician measures it (pure numpy).

* :func:`foot` — the foot of a pulse by the intersecting-tangent method:
  the tangent at the steepest point of the upstroke meets the horizontal
  through the minimum that precedes it;
* :func:`foot_to_foot` — the speed from the feet at two or more probes (the
  least-squares slope of z against the foot times; with two probes, their
  distance over the transit time);
* :func:`loop_speed` — the ΔP–ΔA ("PU-loop") method at one place: in early
  systole, from the foot to the steepest upstroke, the wave runs alone
  (no reflection has come back) and c² = A/ρ_f · dP/dA.

Each returns a :class:`Speed`: a positive number, or None and the reason
there is none (no foot, probes too close, the wave not arrived yet).  A run's
closing lines and ``summary.json``'s ``cycles`` give the foot-to-foot speed
of every cycle (:mod:`multilayer.results.cycles`); compare, study and sweep
theirs of the whole run (:mod:`multilayer.campaign.measures`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import attrs
import numpy as np

from multilayer.results.reading import finite_rows

#: a probe whose pulse rises by less than this fraction of the largest rise among its kind has seen no arrival
#: (what it saw is the small field running ahead of the pulse)
ARRIVED = 0.01
#: the pulse's upstroke is the series' first rise at least this fraction as high as its highest
BEAT = 0.5
#: two rises apart by a dip of less than this fraction of the series' range are one upstroke
MERGE = 0.01
#: feet closer in time than this many rows of the series do not resolve a transit time
MIN_ROWS = 2

@attrs.frozen
class Speed:
    """A speed (cm/s), or None and why there is none."""

    value: float | None
    reason: str = ""

    def cell(self) -> str:
        """The speed as a table shows it: 4 significant digits, or a dash and the reason.

        >>> Speed(512.345).cell(), Speed(None, "no fluid").cell()
        ('512.3', '— (no fluid)')
        """
        return f"{self.value:.4g}" if self.value is not None else f"— ({self.reason})"

    def items(self, key: str) -> dict[str, Any]:
        """``{key: value, key_reason: reason}``, as ``report.json`` holds it."""
        return {key: self.value, f"{key}_reason": self.reason}


def _none(reason: str) -> Speed:
    return Speed(None, reason)


@attrs.frozen
class Foot:
    """The foot of a pulse: ``time`` (None with ``reason`` when there is none), the steepest point of the upstroke
    (``steepest``, the midpoint of the steepest row interval), and the pulse's ``rise`` above its preceding
    minimum (in the series' unit, positive)."""

    time: float | None
    steepest: float | None = None
    rise: float = 0.0
    reason: str = ""


def upstrokes(y: np.ndarray) -> list[tuple[int, int]]:
    """(bottom, top) rows of every rise of ``y``, from a minimum to the next maximum; two rises apart by a dip of
    less than :data:`MERGE` of y's range are one (a wiggle on an upstroke does not split it).

    >>> upstrokes(np.array([0.0, 0.0, 1.0, 3.0, 2.99, 5.0, 4.0, 4.0, 6.0]))
    [(1, 5), (7, 8)]
    """
    d = np.diff(y)
    found: list[list[int]] = []
    j = 0
    while j < len(d):
        if d[j] <= 0.0:
            j += 1
            continue
        k = j
        while j < len(d) and d[j] >= 0.0:
            j += 1
        if found and y[found[-1][1]] - y[k] < MERGE * np.ptp(y):
            found[-1][1] = j
        else:
            found.append([k, j])
    return [(k, m) for k, m in found]


def foot(t: np.ndarray, y: np.ndarray) -> Foot:
    """The foot of the pulse in ``y(t)`` by the intersecting-tangent method.

    The pulse's upstroke is the first of the series' rises (:func:`upstrokes`)
    at least :data:`BEAT` as high as the highest: a start's small transient
    is no beat, and of several beats the first is taken.  Its steepest row
    interval gives the tangent (through the interval's midpoint, with its
    slope: the secant is the tangent there to second order), which meets
    the horizontal through the minimum just before the upstroke at the
    foot.  A pulse that goes down (its largest value negative: a negative
    η) is turned over first.

    >>> t = np.linspace(0.0, 1.0, 11)
    >>> f = foot(t, np.maximum(0.0, t - 0.3) * 2.0)       # a ramp starting at t = 0.3
    >>> round(f.time, 12), round(f.rise, 12)
    (0.3, 1.4)
    >>> foot(t, 1.0 + t).reason
    'the upstroke starts before the first row'
    >>> foot(t, np.maximum(0.0, t - 0.5)**3).reason
    'the upstroke is still steepening on the last row: the pulse has not passed yet'
    """
    t, y = finite_rows(np.asarray(t, dtype=float), np.asarray(y, dtype=float))
    if len(t) < 3:
        return Foot(None, reason=f"{len(t)} rows: too few for a foot")
    if -y.min() > y.max():  # the largest value is negative: a pulse that goes down
        y = -y
    rises = upstrokes(y)
    if not rises:
        return Foot(None, reason="no upstroke: the series never rises")
    highest = max(y[m] - y[k] for k, m in rises)
    k, m = next((k, m) for k, m in rises if y[m] - y[k] >= BEAT * highest)
    slopes = np.diff(y) / np.diff(t)
    i = k + int(np.argmax(slopes[k:m]))
    if k == 0 and slopes[0] >= 0.5 * slopes[i]:
        return Foot(None, reason="the upstroke starts before the first row")
    if i == len(slopes) - 1:
        return Foot(None, reason="the upstroke is still steepening on the last row: the pulse has not passed yet")
    t_mid, y_mid = 0.5 * (t[i] + t[i + 1]), 0.5 * (y[i] + y[i + 1])
    return Foot(float(t_mid - (y_mid - y[k]) / slopes[i]), float(t_mid), float(y[m] - y[k]))


def foot_to_foot(probes: Sequence[tuple[str, float, np.ndarray, np.ndarray]]) -> tuple[Speed, dict[str, Foot]]:
    """The pulse-wave velocity from the feet at ``probes`` ((name, z, t, y) each), and every probe's foot.

    A probe whose rise is below :data:`ARRIVED` of the largest rise has seen
    no arrival.  The speed is the least-squares slope of z against the foot
    times (with two probes, Δz over the transit time); there is none with
    fewer than two feet at different places, with a transit time under
    :data:`MIN_ROWS` rows (probes too close for the series' time steps), or
    when the feet do not come later downstream.

    >>> t = np.linspace(0.0, 0.01, 101)
    >>> pulse = lambda z: np.maximum(0.0, np.sin(np.pi * (t - z / 500.0) / 0.004)) * (t > z / 500.0)
    >>> speed, feet = foot_to_foot([("a", 1.0, t, pulse(1.0)), ("b", 3.0, t, pulse(3.0))])
    >>> round(speed.value, 6), round(feet["b"].time - feet["a"].time, 9)
    (500.0, 0.004)
    """
    if not probes:
        return _none("no probes"), {}
    feet = {name: foot(t, y) for name, _, t, y in probes}
    largest = max((f.rise for f in feet.values() if f.time is not None), default=0.0)
    for name, f in feet.items():
        if f.time is not None and f.rise < ARRIVED * largest:
            feet[name] = attrs.evolve(f, time=None, reason=f"the pulse has not arrived: its rise is "
                                                           f"{f.rise / largest:.1%} of the largest")
    found = [(z, feet[name].time, t) for name, z, t, _ in probes if feet[name].time is not None]
    if len(found) < 2:
        missing = "; ".join(f"{name}: {feet[name].reason}" for name, *_ in probes if feet[name].time is None)
        return _none("fewer than two probes with a foot" + (f" ({missing})" if missing else "")), feet
    z, times = np.array([f[0] for f in found]), np.array([f[1] for f in found])
    if np.ptp(z) == 0.0:
        return _none(f"every foot is at z = {z[0]:g} cm"), feet
    first, last = int(np.argmin(z)), int(np.argmax(z))
    transit = times[last] - times[first]
    rows = np.median(np.concatenate([np.diff(f[2]) for f in found]))
    if abs(transit) < MIN_ROWS * rows:
        return _none(f"probes too close: the foot takes {transit:.3g} s from z = {z[first]:g} to {z[last]:g} cm, "
                     f"under {MIN_ROWS} rows ({rows:.3g} s)"), feet
    dt = times - times.mean()
    slope = float(np.sum(dt * (z - z.mean())) / np.sum(dt * dt))
    if not slope > 0.0:
        return _none(f"the feet do not come later downstream (the foot takes {transit:.3g} s from z = "
                     f"{z[first]:g} to {z[last]:g} cm): a wave running upstream, or reflections"), feet
    return Speed(slope), feet


def section(radius: float, eta: np.ndarray, radial_power: int) -> np.ndarray:
    """The lumen's section at radius R + η under the measure c rᵏ, per unit c: (R + η)^(k+1)/(k + 1)."""
    return (radius + eta) ** (1 + radial_power) / (1 + radial_power)


def loop_speed(t: np.ndarray, pressure: np.ndarray, eta: np.ndarray, radius: float, radial_power: int,
               density: float) -> Speed:
    """The ΔP–ΔA ("PU-loop") speed at one place: c² = A/ρ_f · dP/dA in early systole.

    ``pressure`` (dyn/cm²) and ``eta`` (cm, the lumen's displacement) are
    the series of two probes at the same z.  Early systole runs from the
    pressure's :func:`foot` to its steepest upstroke: there the incoming
    wave is alone.  dP/dA is the least-squares slope of P against the
    section A (:func:`section`) over those rows, A the section at the foot.

    >>> t = np.linspace(0.0, 1.0, 101)
    >>> p = 0.5 * (1.0 - np.cos(2 * np.pi * (t - 0.2) / 0.6)) * (t > 0.2) * (t < 0.8)   # 1 dyn/cm² at most
    >>> c = loop_speed(t, p, p / 4e5, 0.5, 1, 1.0)              # η = P/C0 in a tube: c² = R C0 / (2ρ)
    >>> round(c.value / math.sqrt(0.5 * 4e5 / 2.0), 6)
    1.0
    """
    t, p, e = np.asarray(t, dtype=float), np.asarray(pressure, dtype=float), np.asarray(eta, dtype=float)
    keep = np.isfinite(t) & np.isfinite(p) & np.isfinite(e)
    t, p, e = t[keep], p[keep], e[keep]
    f = foot(t, p)
    if f.time is None:
        return _none(f"no pressure foot: {f.reason}")
    window = (t >= f.time) & (t <= f.steepest)
    if np.count_nonzero(window) < 3:
        return _none(f"early systole (foot to steepest upstroke, {f.time:.3g} to {f.steepest:.3g} s) holds fewer than "
                     f"3 rows")
    area = section(radius, e[window], radial_power)
    if np.ptp(area) == 0.0:
        return _none("the lumen does not move in early systole")
    slope = float(np.polyfit(area, p[window], 1)[0])
    if not slope > 0.0:
        return _none("pressure and section do not rise together in early systole")
    start = section(radius, float(np.interp(f.time, t, e)), radial_power)
    return Speed(math.sqrt(start * slope / density))
