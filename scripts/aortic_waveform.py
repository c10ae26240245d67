"""Write ``cases/data/aortic-pressure.csv``: one smooth, aortic-like pressure cycle.

The waveform is a formula, not measured data. With s = t/T_c ∈ [0, 1) the
phase in the cycle and G(s; c, w) = Σ_{k=-1,0,1} exp(−((s − c + k)/w)²) a
periodic Gaussian bump,

    w(s) = G(s; 0.16, 0.075)          systolic upstroke and peak
         + 0.45 G(s; 0.30, 0.08)      late-systolic shoulder (reflected wave)
         − 0.12 G(s; 0.38, 0.018)     dicrotic notch (aortic valve closure)
         + 0.12 G(s; 0.44, 0.04)      dicrotic wave
         + 0.30 G(s; 0.55, 0.30)      diastolic run-off

    p(s) = 80 + 40 (w(s) − min w)/(max w − min w)   [mmHg]

so the pressure runs from 80 (diastolic) to 120 mmHg (systolic), peaks at
s ≈ 0.18 and shows a notch near s ≈ 0.38, as an aortic trace does. The file
holds one cycle of T_c = 0.8 s (75 beats/min) in physical time and mmHg:
the case file scales the pressure (``scale``) and the time axis is written
compressed by the factor given on the command line (default 40, so a cycle
lasts 0.02 s), because the compliant channel of theory §9 is 6 cm long and a
full 0.8 s cycle at Δt = 1e-4 would take 8000 steps per beat.

    python scripts/aortic_waveform.py [compression] [file]

writes ``cases/data/aortic-pressure.csv`` (compression 40, the bundled
``physiological-waveform`` case) or the named file in ``cases/data/``; the
RCR-outlet case ``physiological-rcr`` uses the physical cycle,
``python scripts/aortic_waveform.py 1 aortic-pressure-0.8s.csv``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

CYCLE = 0.8     # s, 75 beats/min
POINTS = 200    # samples per cycle (the table closes the cycle linearly)


def bump(s: np.ndarray, centre: float, width: float) -> np.ndarray:
    return sum(np.exp(-(((s - centre + k) / width) ** 2)) for k in (-1, 0, 1))


def shape(s: np.ndarray) -> np.ndarray:
    """w(s) of the module docstring."""
    return (bump(s, 0.16, 0.075) + 0.45 * bump(s, 0.30, 0.08) - 0.12 * bump(s, 0.38, 0.018)
            + 0.12 * bump(s, 0.44, 0.04) + 0.30 * bump(s, 0.55, 0.30))


def waveform(s: np.ndarray) -> np.ndarray:
    """Pressure (mmHg) at the phases ``s`` of the cycle."""
    wf = shape(np.linspace(0.0, 1.0, 4001))
    return 80.0 + 40.0 * (shape(s) - wf.min()) / (wf.max() - wf.min())


def write_table(name: str, comments: list[str], column: str, t: np.ndarray, values: np.ndarray,
                value_format: str) -> Path:
    """``cases/data/<name>``: the ``comments`` lines (each after '# '), the header ``t,<column>``, then the rows."""
    out = Path(__file__).parents[1] / "cases" / "data" / name
    lines = [f"# {c}" for c in comments] + [f"t,{column}"]
    lines += [f"{ti:.8e},{vi:{value_format}}" for ti, vi in zip(t, values)]
    out.write_text("\n".join(lines) + "\n")
    return out


def main(argv: list[str]) -> None:
    compression = float(argv[0]) if argv else 40.0
    s = np.arange(POINTS) / POINTS
    t = s * CYCLE / compression
    p = waveform(s)
    name = argv[1] if len(argv) > 1 else "aortic-pressure.csv"
    out = write_table(name, [f"aortic-like pressure cycle written by scripts/aortic_waveform.py (compression "
                             f"{compression:g}):", f"one {CYCLE:g} s cycle shown in {CYCLE / compression:g} s; "
                             f"p in mmHg (80-120)"], "p", t, p, ".6f")
    print(f"wrote {out}: {POINTS} points, p in [{p.min():.2f}, {p.max():.2f}] mmHg, "
          f"peak at s = {s[np.argmax(p)]:.3f}")


if __name__ == "__main__":
    main(sys.argv[1:])
