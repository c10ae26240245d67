"""Reading frequencies and decay rates off a computed time series.

A linear time-stepping scheme maps each discrete mode by a fixed complex
factor z per step.  :func:`prony_roots` recovers those factors from a
sampled signal by a least-squares fit of a linear recurrence; for backward
Euler on a first-order system, z = 1/(1 − λΔt) exactly, so
:func:`backward_euler_eigenvalue` turns z back into the semi-discrete
eigenvalue λ.
"""

from __future__ import annotations

import numpy as np


def prony_roots(signal: np.ndarray, order: int = 2) -> np.ndarray:
    """Roots z of the recurrence s[n] = Σ_k c_k s[n−k] that best fits ``signal``.

    >>> z = 0.99 * np.exp(0.3j)
    >>> s = (z ** np.arange(40)).real
    >>> r = prony_roots(s)
    >>> bool(np.allclose(sorted(np.abs(np.angle(r))), [0.3, 0.3]))
    True
    """
    s = np.asarray(signal, dtype=float)
    n = len(s)
    A = np.column_stack([s[order - k - 1:n - k - 1] for k in range(order)])
    c, *_ = np.linalg.lstsq(A, s[order:], rcond=None)
    return np.roots(np.concatenate([[1.0], -c]))


def backward_euler_eigenvalue(z: complex, dt: float) -> complex:
    """λ with z = 1/(1 − λΔt): the semi-discrete eigenvalue behind a BE factor.

    >>> lam = backward_euler_eigenvalue(1 / (1 - (-1 + 2j) * 0.1), 0.1)
    >>> bool(abs(lam - (-1 + 2j)) < 1e-12)
    True
    """
    return complex((1.0 - 1.0 / z) / dt)


def oscillation(signal: np.ndarray, dt: float) -> tuple[float, float]:
    """(angular frequency ω, decay rate) of a signal dominated by one damped mode."""
    z = prony_roots(signal, 2)
    z = z[np.argmax(np.abs(np.angle(z)))]
    return abs(np.angle(z)) / dt, float(np.log(abs(z)) / dt)
