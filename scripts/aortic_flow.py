"""Write ``cases/data/aortic-flow-1s.csv``: one smooth, aortic-like inflow cycle of 1 s.

The waveform is a formula, not measured data. With s = t/T_c ∈ [0, 1) the
phase in the cycle and G(s; c, w) = Σ_{k=-1,0,1} exp(−((s − c + k)/w)²) a
periodic Gaussian bump,

    w(s) = G(s; 0.36, 0.050)          ejection: upstroke and peak
         + 0.40 G(s; 0.45, 0.050)     late ejection
         − 0.10 G(s; 0.56, 0.018)     brief backflow at aortic valve closure

    Q(s) = Q_mean w(s) / mean(w)      [cm²/s per unit depth]

so the valve ejects over s ≈ 0.25–0.55 and the flow is all but zero (below
3e-5 of its peak) over the diastole s ≈ 0.65–1.2, as an ascending-aortic
flow trace is at 60 beats/min. The cycle starts in mid-diastole (s = 0) so
that a run can start from rest at diastolic pressure with no flow to switch
on; Q(0) is 1e-23 of the peak. Q_mean = 0.75 cm²/s puts the mean pressure of
``cases/physiological-flow.toml``'s Windkessel (R_p + R_d = 4 400 dyn·s/cm³
per unit depth) near 3 300 dyn/cm², the 100 mmHg of the scaled wall (1/40 of
physical, as in ``physiological-rcr``).

    python scripts/aortic_flow.py
"""

from __future__ import annotations

import numpy as np

# the sibling script's periodic bump and table writer
from aortic_waveform import bump, write_table

CYCLE = 1.0       # s, 60 beats/min
POINTS = 400      # samples per cycle (2.5 ms apart; the case interpolates them with a periodic cubic)
Q_MEAN = 0.75     # cm²/s per unit depth


def shape(s: np.ndarray) -> np.ndarray:
    return bump(s, 0.36, 0.05) + 0.40 * bump(s, 0.45, 0.05) - 0.10 * bump(s, 0.56, 0.018)


def waveform(s: np.ndarray) -> np.ndarray:
    """Inflow (cm²/s per unit depth) at the phases ``s`` of the cycle."""
    fine = np.arange(20000) / 20000
    return Q_MEAN * shape(s) / shape(fine).mean()


def main() -> None:
    s = np.arange(POINTS) / POINTS
    q = waveform(s)
    out = write_table("aortic-flow-1s.csv", ["aortic-like inflow cycle written by scripts/aortic_flow.py:",
                                             f"one {CYCLE:g} s cycle (60 beats/min); Q in cm^2/s per unit depth, "
                                             f"mean {Q_MEAN:g}"], "Q", s * CYCLE, q, ".9e")
    quiet = np.abs(q[(s > 0.65) | (s < 0.2)]).max() / q.max()
    print(f"wrote {out}: {POINTS} points, Q in [{q.min():.4f}, {q.max():.4f}] cm^2/s, peak at s = "
          f"{s[np.argmax(q)]:.3f}, |Q|/max Q < {quiet:.2e} over s in (0.65, 1.2), Q(0)/max Q = {q[0] / q.max():.1e}")


if __name__ == "__main__":
    main()
