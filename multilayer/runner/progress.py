"""What a run shows while it goes and when it ends.

A progress bar (tqdm) on stderr whose total is the simulated time, with the
step, the estimated time left and the current ledger residual — only on a terminal,
and never with ``--quiet`` — and a short summary at the end.
"""

from __future__ import annotations

import sys
from pathlib import Path

from tqdm import tqdm

from multilayer.results.cycles import last_cycle_line
from multilayer.results.readouts import range_lines


class ProgressBar:
    """Called after every step with the run's tally and the step's row (see :func:`multilayer.runner.loop.run_case`).

    Its total is the simulated time, ``end`` seconds (from ``start``, a resumed run's, at its ``step``): it
    moves with t, so the bar and its estimate of the time left mean the same with fixed steps and with steps
    chosen by error, whose number is not known ahead.  The postfix holds the step and the ledger's residual.

    >>> bar = ProgressBar(0.5, 0.1, enabled=False)
    >>> bar.bar.total, bar.bar.n
    (0.5, 0.1)
    """

    def __init__(self, end: float, start: float = 0.0, enabled: bool | None = None, step: int = 0):
        enabled = sys.stderr.isatty() if enabled is None else enabled
        self.end = end
        self.bar = tqdm(total=end, initial=start, unit="s", disable=not enabled, file=sys.stderr, dynamic_ncols=True,
                        leave=False, postfix=f"step {step}",
                        bar_format="{l_bar}{bar}| t = {n:.4g}/{total:.4g} s [{elapsed}<{remaining}{postfix}]")

    def __call__(self, tally, row) -> None:
        self.bar.set_postfix_str(f"step {tally.steps}, ledger {row['energy.relative_residual']:.1e}", refresh=False)
        self.bar.update(min(tally.t, self.end) - self.bar.n)

    def close(self) -> None:
        self.bar.close()


def summary(result, wall_time_s: float, folder: Path, checkpoint: bool = False) -> str:
    """A few lines: status, steps, wall time, ledger residuals (energy, volume), peak |η| per probe (in µm),
    the pressures' ranges (mmHg, then dyn/cm²) and the flow rates' (mL/s in a tube), the last complete cardiac cycle
    (under a periodic load), where the results are."""
    volume = ""
    if result.volume_drift is not None:
        volume = f", volume to {result.volume_drift:.1e} of the volume moved"
    lines = [f"{result.status}: {result.steps} steps to t = {result.t:.6g} s in {wall_time_s:.3g} s; "
             f"energy ledger closes to {result.max_relative_residual:.1e} (relative){volume}"]
    if result.reason:
        lines.append(f"  {result.reason}")
    if result.peaks:
        lines.append("  peak |η|: " + ", ".join(f"{name} {1e4 * value:.4g} µm" for name, value in result.peaks.items()))
    lines += [f"  {line}" for line in range_lines(getattr(result, "ranges", None) or {})]
    cycle = last_cycle_line(getattr(result, "cycles", None))
    if cycle:
        lines.append(f"  {cycle}")
    lines.append(f"  results in {folder}")
    if result.status == "interrupted" and checkpoint:
        lines.append(f"  resume with: multilayer resume {folder}")
    return "\n".join(lines)
