"""Runs read back (:class:`~multilayer.results.reading.RunData`) measured against a reference, as Markdown rows.

The measures behind docs/verification.md (``scripts/verification_report.py``)
and the scripts that print one table of it (``scripts/side_by_side.py``,
``scripts/peak_table.py``, ``scripts/scene_checks.py``): the errors of a
run's probes against a reference run (:func:`errors_against`), its peaks
against the reference's (:func:`peak_changes`), a hemodynamics scene's
checks (:func:`scene_cells`, :func:`centreline_changes`), and the steps a
run took (:func:`steps_taken`).  Pure functions of the runs' data: nothing
here runs a case.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from multilayer.campaign.accuracy import probe_errors
from multilayer.plugin.units import MMHG
from multilayer.results.reading import RunData

#: cm/s: the section's mean velocity above which a centreline ratio is read (below it the ratio means nothing)
FLOWING = 5.0


def markdown(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> list[str]:
    """A Markdown table's lines.

    >>> markdown(["a", "b"], [[1, "x"]])
    ['| a | b |', '|---|---|', '| 1 | x |']
    """
    return (["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
            + ["| " + " | ".join(str(c) for c in row) + " |" for row in rows])


def percent(x: float | None, digits: int = 3) -> str:
    """``x`` (a fraction) in per cent to ``digits`` significant digits; "—" for None or NaN.

    >>> percent(0.001234), percent(None)
    ('0.123 %', '—')
    """
    if x is None or not np.isfinite(x):
        return "—"
    return f"{100 * x:.{digits}g} %"


def errors_against(run: RunData, reference: RunData, probes: Sequence[str], after: float = 0.0) -> tuple[float, float]:
    """(relative L∞ error, peak error) of ``run`` against ``reference``, each the largest over ``probes``.

    Over the rows with t ≥ ``after`` of both series (a periodic run's last
    cycle); the reference is interpolated linearly onto the run's times
    (:func:`multilayer.campaign.accuracy.probe_errors`).
    """
    mine, theirs = np.asarray(run.t) >= after, np.asarray(reference.t) >= after
    found = [probe_errors(np.asarray(run.t)[mine], np.asarray(run.series[p])[mine], np.asarray(reference.t)[theirs],
                          np.asarray(reference.series[p])[theirs]) for p in probes]
    linf = [e["relative_linf"] for e in found]
    peak = [e["peak_error"] for e in found]
    nan = float("nan")
    return (max(linf) if None not in linf else nan), (max(peak) if None not in peak else nan)


def peaks(run: RunData, probes: Sequence[str]) -> np.ndarray:
    """The largest value over time of each probe."""
    return np.array([np.max(run.series[p]) for p in probes])


def peak_changes(run: RunData, reference: RunData, probes: Sequence[str]) -> np.ndarray:
    """The relative difference of each probe's peak from the reference's."""
    return peaks(run, probes) / peaks(reference, probes) - 1.0


def signed_percent(x: float) -> str:
    """A signed relative change in per cent, two decimals, with a true minus sign.

    >>> signed_percent(-0.0123), signed_percent(0.5)
    ('−1.23 %', '+50.00 %')
    """
    return f"{100 * x:+.2f} %".replace("-", "−")


def steps_taken(summary: Mapping[str, Any]) -> tuple[int, int, tuple[float, float]]:
    """(accepted steps, rejected steps, (smallest, largest) Δt) of a run's ``summary.json``."""
    adaptive = summary.get("adaptive") or {}
    small, large = adaptive.get("dt_range", [summary.get("dt", float("nan"))] * 2)
    return adaptive.get("accepted", summary.get("steps", 0)), adaptive.get("rejected", 0), (small, large)


def dt_cell(small: float, large: float) -> str:
    """The steps' range, or the one Δt of fixed steps.

    >>> dt_cell(1e-4, 1e-4), dt_cell(2.5e-5, 1e-3)
    ('0.0001', '2.5e-05 … 0.001')
    """
    return f"{small:.3g}" if small == large else f"{small:.3g} … {large:.3g}"


def scene_cells(run: RunData, radius: float, pairs: Sequence[tuple[str, str, str]], pressure: str = "p_out",
                period: float = 1.0) -> list[str]:
    """A hemodynamics run's checks: status, steps, ledger, volume drift, pressure over the last period (mmHg), its
    largest change from the period before, and per ``(centreline probe, section flow rate, section η)`` the range
    of the centreline velocity over the section's mean velocity Q/(π(R + η)²) where that mean exceeds :data:`FLOWING`.
    """
    s, t, summary = run.series, run.t, run.summary
    p = s[pressure] / MMHG
    last = t > t[-1] - period
    before = (t > t[-1] - 2 * period) & ~last
    periodic = "—"
    if t[-1] >= 2 * period - 1e-9 and before.any():
        shifted = np.interp(t[last] - period, t[before], p[before])
        periodic = f"{np.max(np.abs(p[last] - shifted)) / np.max(np.abs(p[last])):.2%}"
    ratios = []
    for probe, section, eta in pairs:
        mean = s[section] / (np.pi * (radius + s[eta]) ** 2)
        flowing = mean > FLOWING
        r = s[probe][flowing] / mean[flowing]
        ratios.append(f"{r.min():.2f} … {r.max():.2f}")
    return [summary["status"], str(summary["steps"]), f"{summary['energy']['max_relative_residual']:.1e}",
            f"{summary['volume']['relative_drift']:.2e}", f"{p[last].min():.1f} … {p[last].max():.1f}", periodic,
            *ratios]


def scene_header(pairs: Sequence[tuple[str, str, str]], pressure: str = "p_out") -> list[str]:
    """The columns of :func:`scene_cells` (after the run's name)."""
    return ["status", "steps", "energy", "volume drift", f"{pressure} last cycle (mmHg)", "periodic",
            *(f"{probe} / mean" for probe, _, _ in pairs)]


def centreline_changes(a: RunData, b: RunData, probes: Sequence[str], t0: np.ndarray) -> list[float]:
    """The largest change of each probe from run ``a`` to run ``b`` at the times ``t0`` (both interpolated)."""
    return [float(np.max(np.abs(np.interp(t0, a.t, a.series[p]) - np.interp(t0, b.t, b.series[p])))) for p in probes]
