"""The fewest steps a step distribution needs for a fixed-Δt run's error, over the fixed run's count.

    python scripts/step_bound.py RUN_FOLDER --probes eta_z1,eta_z2 [--stride 4] [--between T0,T1]

From a resolved run's ``series.csv`` (a reference), g(t) = the largest over the
probes of |x'''(t)| / max_t |x| (third differences of every ``stride``-th row).
A second-order rule's local errors are c·kₙ³·g(tₙ); summed without
cancellation over a run they give the error E = c ∫ k² g dt, and the steps
number N = ∫ dt/k. Two distributions are compared with even steps, whose
count for the same E is T sqrt(∫ g dt / (E/c)):

* the fewest steps (Lagrange: kₙ ∝ g^(−1/3), every step's local error the
  same): N = (∫ g^⅓ dt)^(3/2) / sqrt(E/c), so the ratio

      optimal = (∫ g^⅓ dt)^(3/2) / (T sqrt(∫ g dt))  ≤ 1   (Hölder);

* error per unit step (kₙ ∝ g^(−1/2), every step's local error the same
  fraction of its length, what a tolerance per elapsed time gives):

      per unit step = (∫ g^½ dt) / sqrt(T ∫ g dt)  ≤ 1   (Cauchy–Schwarz).

Both are 1 for an even g. docs/accuracy.md uses them: a waveform busy all
through its cycle leaves adaptive steps nothing to save.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from multilayer.results.reading import read_run


def step_ratios(t: np.ndarray, series: list[np.ndarray]) -> tuple[float, float]:
    """The (optimal, per unit step) ratios of the module docstring from the even samples ``t``.

    >>> t = np.linspace(0.0, 1.0, 401)
    >>> [round(r, 2) for r in step_ratios(t, [t ** 3])]          # x''' even: nothing to save
    [1.0, 1.0]
    >>> s = np.minimum(t, 0.5)                       # x''' = 1 on the first half, 0 on the second (C²)
    >>> [round(r, 2) for r in step_ratios(t, [s ** 3 / 6 + s ** 2 / 2 * (t - s) + s / 2 * (t - s) ** 2])]
    [0.5, 0.71]
    """
    h = t[1] - t[0]
    g = np.max([np.abs(np.diff(x, 3)) / h ** 3 / np.max(np.abs(x)) for x in series], axis=0)
    span = h * g.size
    optimal = (np.sum(np.cbrt(g)) * h) ** 1.5 / (span * np.sqrt(np.sum(g) * h))
    return float(optimal), float(np.sum(np.sqrt(g)) * h / np.sqrt(span * np.sum(g) * h))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("--probes", required=True, help="comma list of probe names")
    ap.add_argument("--stride", type=int, default=4, help="use every stride-th row (smooths the differences)")
    ap.add_argument("--between", default=None, help="T0,T1: only the rows with T0 ≤ t ≤ T1 (one cycle, say)")
    args = ap.parse_args(argv)
    run = read_run(args.run.name, args.run)
    t0, t1 = (float(x) for x in args.between.split(",")) if args.between else (-np.inf, np.inf)
    within = (np.asarray(run.t) >= t0 - 1e-12) & (np.asarray(run.t) <= t1 + 1e-12)
    t = np.asarray(run.t)[within][:: args.stride]
    series = [np.asarray(run.series[p])[within][:: args.stride] for p in args.probes.split(",")]
    optimal, per_unit_step = step_ratios(t, series)
    print(f"h = {t[1] - t[0]:.3g} s: steps / even steps at equal error: optimal {optimal:.3f}, "
          f"per unit step {per_unit_step:.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
