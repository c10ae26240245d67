"""How accurate a run is, and what accuracy costs: pure functions of numbers and arrays.

A study (:mod:`multilayer.campaign.study`) measures each run against a
reference with :func:`relative_linf` and :func:`probe_errors`, the observed
order of a Δt sequence with :func:`observed_orders`, the reference's own
error with :func:`richardson` and :func:`richardson_order`, the runs no other
beats on wall time and error with :func:`pareto_front`, and the wall time to
reach a target error with :func:`cost_to_target`.  They work on any series,
e.g. runs made by hand and read with :func:`multilayer.results.reading.read_run`.
See ``docs/study.md``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.optimize import brentq

from multilayer.results.reading import finite_rows


def _common_span(t: np.ndarray, t_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Masks of the rows of ``t`` and of ``t_ref`` inside the time span both cover."""
    if not len(t) or not len(t_ref):
        return None
    lo, hi = max(t[0], t_ref[0]), min(t[-1], t_ref[-1])
    on, ref_on = (t >= lo) & (t <= hi), (t_ref >= lo) & (t_ref <= hi)
    return (on, ref_on) if on.any() and ref_on.any() else None


def relative_linf(t: np.ndarray, y: np.ndarray, t_ref: np.ndarray, y_ref: np.ndarray) -> float | None:
    """max_t |y − y_ref| / max_t |y_ref|, the reference interpolated linearly onto ``t``.

    Only the times both series cover count: a row of ``t`` outside the
    reference's span is skipped.  The scale max |y_ref| is taken over the
    reference's own rows in that span, so it does not depend on the run.

    Parameters
    ----------
    t, y : ndarray
        The run's times (s) and values; rows with a NaN are left out.
    t_ref, y_ref : ndarray
        The reference's, on its own (usually finer) time grid.

    Returns
    -------
    float or None
        The relative error; None without common rows or when the reference
        is 0 on them.

    Examples
    --------
    >>> t_ref = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    >>> relative_linf(np.array([1.0, 2.0, 3.0]), np.array([0.0, 1.5, 0.0]), t_ref, np.array([0.0, 0.0, 1.0, 0.0, 0.0]))
    0.5
    >>> relative_linf(np.array([1.0, 2.0, 5.0]), np.array([0.0, 1.5, 9.0]), t_ref, np.array([0.0, 0.0, 1.0, 0.0, 0.0]))
    0.5
    """
    (t, y), (t_ref, y_ref) = finite_rows(t, y), finite_rows(t_ref, y_ref)
    span = _common_span(t, t_ref)
    if span is None:
        return None
    on, ref_on = span
    scale = float(np.max(np.abs(y_ref[ref_on])))
    if scale == 0.0:
        return None
    return float(np.max(np.abs(y[on] - np.interp(t[on], t_ref, y_ref)))) / scale


def probe_errors(t: np.ndarray, y: np.ndarray, t_ref: np.ndarray, y_ref: np.ndarray) -> dict[str, float | None]:
    """A run's ``eta`` series against the reference's, over the times both cover.

    ``relative_linf`` (:func:`relative_linf`); ``peak`` = max η and
    ``peak_time`` its (first) time, each series over its own rows;
    ``peak_error`` = |peak − peak_ref| / |peak_ref|; ``arrival_diff_s`` =
    peak_time − peak_time_ref.

    Parameters
    ----------
    t, y, t_ref, y_ref : ndarray
        As for :func:`relative_linf`.

    Returns
    -------
    dict
        ``relative_linf``, ``peak``, ``peak_time``, ``peak_ref``,
        ``peak_time_ref``, ``peak_error``, ``arrival_diff_s``; all None
        without common times.

    Examples
    --------
    >>> e = probe_errors(np.array([1.0, 2.0, 3.0]), np.array([0.0, 0.9, 0.3]),
    ...                  np.array([0.5, 1.5, 2.5, 3.5]), np.array([0.0, 0.5, 1.0, 0.2]))
    >>> e["peak_error"], e["arrival_diff_s"]
    (0.09999999999999998, -0.5)
    """
    none = dict.fromkeys(("relative_linf", "peak", "peak_time", "peak_ref", "peak_time_ref", "peak_error",
                          "arrival_diff_s"))
    (t, y), (t_ref, y_ref) = finite_rows(t, y), finite_rows(t_ref, y_ref)
    span = _common_span(t, t_ref)
    if span is None:
        return none
    on, ref_on = span
    i, j = int(np.argmax(y[on])), int(np.argmax(y_ref[ref_on]))
    peak, peak_ref = float(y[on][i]), float(y_ref[ref_on][j])
    peak_time, peak_time_ref = float(t[on][i]), float(t_ref[ref_on][j])
    return {
        "relative_linf": relative_linf(t, y, t_ref, y_ref),
        "peak": peak, "peak_time": peak_time, "peak_ref": peak_ref, "peak_time_ref": peak_time_ref,
        "peak_error": abs(peak - peak_ref) / abs(peak_ref) if peak_ref else None,
        "arrival_diff_s": peak_time - peak_time_ref,
    }


def observed_orders(dt: Sequence[float], errors: Sequence[float | None]) -> list[float | None]:
    """p = log(e_coarse/e_fine) / log(dt_coarse/dt_fine) between successive Δt (coarse to fine).

    Parameters
    ----------
    dt : sequence of float
        The time steps, strictly decreasing (ValueError otherwise).
    errors : sequence of float or None
        The error of each run.

    Returns
    -------
    list of float or None
        ``result[i]`` is the order between runs i and i + 1; None where an
        error is missing or not > 0.

    Examples
    --------
    >>> observed_orders([4e-4, 2e-4, 1e-4], [8.0, 4.0, None])
    [1.0, None]
    """
    if any(a <= b for a, b in zip(dt, dt[1:])):
        raise ValueError(f"Δt must decrease strictly: {list(dt)}")
    out: list[float | None] = []
    for (dt_c, e_c), (dt_f, e_f) in zip(zip(dt, errors), zip(dt[1:], errors[1:])):
        ok = e_c is not None and e_f is not None and e_c > 0 and e_f > 0
        out.append(math.log(e_c / e_f) / math.log(dt_c / dt_f) if ok else None)
    return out


def pareto_front(cost: Sequence[float], error: Sequence[float]) -> list[int]:
    """Indices of the points no other point beats: none as cheap and as accurate, and better in one.

    Parameters
    ----------
    cost, error : sequence of float
        Wall time and error of each point.

    Returns
    -------
    list of int
        The indices of the non-dominated points, in their order; two equal
        points do not beat each other.

    Examples
    --------
    >>> pareto_front([1.0, 2.0, 3.0, 2.5, 1.0], [0.5, 0.1, 0.01, 0.2, 0.6])
    [0, 1, 2]
    """
    return [i for i, (c, e) in enumerate(zip(cost, error))
            if not any(c2 <= c and e2 <= e and (c2 < c or e2 < e) for c2, e2 in zip(cost, error))]


def richardson(difference: float, ratio: float, order: float) -> float:
    """Richardson's error estimate of the finer of two runs: |X_fine − X_coarse| / (r^p − 1).

    For X(Δt) = X + C Δt^p and r = Δt_coarse/Δt_fine it is exactly |X(Δt_fine) − X|.

    Parameters
    ----------
    difference : float
        |X_fine − X_coarse|, in whatever measure X is compared.
    ratio : float
        r = Δt_coarse / Δt_fine > 1.
    order : float
        p, observed or formal.

    Returns
    -------
    float
        The estimated error of the finer run.

    Examples
    --------
    >>> richardson(0.3, 2.0, 1.0), richardson(0.4, 3.0, 2.0)
    (0.3, 0.05)
    """
    return difference / (ratio**order - 1.0)


def richardson_order(dt: Sequence[float], d_coarse: float, d_fine: float) -> float | None:
    """The order p of X(Δt) = X + C Δt^p seen in three runs Δt₀ > Δt₁ > Δt₂.

    ``d_coarse`` = |X(Δt₀) − X(Δt₁)|, ``d_fine`` = |X(Δt₁) − X(Δt₂)|.  With
    one ratio r it is log(d_coarse/d_fine)/log r; otherwise the root of
    (Δt₀^p − Δt₁^p)/(Δt₁^p − Δt₂^p) = d_coarse/d_fine in p ∈ [0.01, 20].

    Parameters
    ----------
    dt : sequence of three floats
        Δt₀ > Δt₁ > Δt₂.
    d_coarse, d_fine : float
        The two successive differences.

    Returns
    -------
    float or None
        p; None when a difference is not > 0 or there is no root.

    Examples
    --------
    >>> richardson_order([4.0, 2.0, 1.0], 12.0, 3.0)
    2.0
    >>> round(richardson_order([5.0, 2.0, 1.0], 21.0, 3.0), 12)
    2.0
    """
    if not (d_coarse > 0 and d_fine > 0):
        return None
    x0, x1 = dt[0] / dt[2], dt[1] / dt[2]
    q = d_coarse / d_fine
    if math.isclose(x0 / x1, x1, rel_tol=1e-9):
        return math.log(q) / math.log(x1)
    def mismatch(p: float) -> float:
        return (x0**p - x1**p) / (x1**p - 1.0) - q

    lo, hi = 0.01, 20.0
    if mismatch(lo) * mismatch(hi) > 0:
        return None
    return float(brentq(mismatch, lo, hi, xtol=1e-14, rtol=1e-14))


def cost_to_target(wall: Sequence[float], error: Sequence[float], target: float, finest: int | None = None,
                   order: float | None = None) -> dict[str, Any]:
    """Wall time to bring the error to ``target``, from one coupler's runs.

    The cheapest run with error ≤ target (``how`` = "measured"); else an
    extrapolation from the finest run ``finest`` with the observed order
    p: the time grows like 1/Δt and the error like Δt^p, so
    t = t_run·(e_run/target)^(1/p) ("estimated"); "not reached" without
    such a run or a p > 0.

    Parameters
    ----------
    wall, error : sequence of float
        Wall time (s) and error of each run of the coupler.
    target : float
        The error to reach.
    finest : int, optional
        Index of the run to extrapolate from.
    order : float, optional
        The observed order p of the error near that run.

    Returns
    -------
    dict
        ``how``, ``wall_time_s`` (None when not reached), ``run`` (the
        index measured or extrapolated from), ``order`` (p when estimated).

    Examples
    --------
    >>> cost_to_target([1.0, 2.0, 4.0], [0.2, 0.1, 0.05], 0.1)
    {'how': 'measured', 'wall_time_s': 2.0, 'run': 1, 'order': None}
    >>> cost_to_target([1.0, 2.0, 4.0], [0.2, 0.1, 0.05], 0.0125, finest=2, order=2.0)
    {'how': 'estimated', 'wall_time_s': 8.0, 'run': 2, 'order': 2.0}
    >>> cost_to_target([1.0], [0.2], 0.01, finest=0)["how"]
    'not reached'
    """
    met = [i for i, e in enumerate(error) if e <= target]
    if met:
        i = min(met, key=lambda k: wall[k])
        return {"how": "measured", "wall_time_s": wall[i], "run": i, "order": None}
    if finest is not None and order is not None and order > 0:
        return {"how": "estimated", "wall_time_s": wall[finest] * (error[finest] / target) ** (1.0 / order),
                "run": finest, "order": order}
    return {"how": "not reached", "wall_time_s": None, "run": None, "order": None}


def cost_cell(cost: dict[str, Any]) -> str:
    """A :func:`cost_to_target` result as a table cell: the wall time (s), marked when estimated.

    >>> cost_cell(cost_to_target([1.0, 2.0], [0.2, 0.1], 0.1)), cost_cell({"wall_time_s": None})
    ('2', 'not reached')
    >>> cost_cell(cost_to_target([1.0, 2.0, 4.0], [0.2, 0.1, 0.05], 0.0125, finest=2, order=2.0))
    '8 (estimated, p = 2.00)'
    """
    if cost["wall_time_s"] is None:
        return "not reached"
    return f"{cost['wall_time_s']:.3g}" + (f" (estimated, p = {cost['order']:.2f})"
                                           if cost["how"] == "estimated" else "")
