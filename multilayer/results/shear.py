"""The wall shear stress over cardiac cycles: TAWSS and OSI along the lumen (pure numpy over ``wss_lumen.csv``).

For τ_w(z, t) at the lumen's positions (dyn/cm², signed: positive downstream)
and a complete cycle [a, a + T] (:func:`multilayer.results.cycles.windows`),

    TAWSS(z) = (1/T) ∫ |τ_w| dt,      OSI(z) = ½ (1 − |∫ τ_w dt| / ∫ |τ_w| dt),

the time integrals as :func:`multilayer.results.cycles.integral` takes them.
OSI is 0 where τ_w keeps its sign over the cycle and ½ where it reverses so
that it averages to zero; it is undefined (None) where τ_w is 0 throughout.
"""

from __future__ import annotations

import math

import numpy as np

from multilayer.results.cycles import integral, windows
from multilayer.results.reading import without_nan


def tawss_osi(t: np.ndarray, wss: np.ndarray, a: float, b: float, start: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(TAWSS, OSI) per position over [a, b] of ``wss`` (rows × positions).

    >>> t = np.arange(1, 101) * 0.01
    >>> w = np.column_stack([np.full_like(t, 2.0), np.sin(2 * np.pi * t), 1.0 + 2.0 * np.sin(2 * np.pi * t)])
    >>> tawss, osi = tawss_osi(t, w, 0.0, 1.0)
    >>> tawss.round(3).tolist(), osi.round(3).tolist()  # exact: 2, 2/π, 1/3 + 2√3/π; 0, ½, ½(1 − 1/(1/3 + 2√3/π))
    ([2.0, 0.636, 1.436], [0.0, 0.5, 0.152])
    """
    signed = integral(t, wss, a, b, start)
    magnitude = integral(t, np.abs(wss), a, b, start)
    with np.errstate(invalid="ignore", divide="ignore"):
        osi = np.where(magnitude > 0.0, 0.5 * (1.0 - np.abs(signed) / magnitude), np.nan)
    return magnitude / (b - a), osi


def summarize(t: np.ndarray, z: np.ndarray, wss: np.ndarray, period: float | None, start: float = 0.0) -> dict:
    """The ``wss`` block of ``summary.json``: positions, the peak |τ_w| over the run and, with a period, TAWSS and
    OSI per complete cycle with the change of TAWSS from the cycle before.

    ``change`` is max_z |ΔTAWSS| / max_z TAWSS of the cycle before: it goes to zero as the run becomes periodic.
    """
    t, wss = np.asarray(t, dtype=float), np.asarray(wss, dtype=float)
    out: dict = {"unit": "dyn/cm²", "z": [float(v) for v in z],
                 "peak": (np.nanmax(np.abs(wss), axis=0) if len(t) else np.full(len(z), np.nan)).tolist()}
    if period is None:
        return without_nan(out)
    out["period"] = period
    out["cycles"] = []
    before = None
    for k, a, b in windows(t, period, start):
        tawss, osi = tawss_osi(t, wss, a, b, start)
        cycle = {"index": k, "start": a, "end": b, "tawss": tawss.tolist(), "osi": osi.tolist()}
        if before is not None:
            scale = float(np.nanmax(before)) if np.any(np.isfinite(before)) else math.nan
            cycle["change"] = float(np.nanmax(np.abs(tawss - before))) / scale if scale > 0.0 else math.nan
        out["cycles"].append(cycle)
        before = tawss
    return without_nan(out)
