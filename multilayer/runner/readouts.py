"""What a hemodynamics user reads of a finished run: the ``cycles`` and ``wss`` blocks of ``summary.json``.

Both are computed once the run has stopped, from the tables it wrote
(``series.csv``, ``wss_lumen.csv``; read back, so a resumed run's rows
before its checkpoint count too) by the pure functions of
:mod:`multilayer.results.cycles` and :mod:`multilayer.results.shear`.  This
module only gathers their inputs from the case: the loads' period, which
columns are pressures and where (their feet give the pulse-wave velocity), the
inflow, the lumen's section at the ``eta`` probes.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from multilayer.case.model import Case
from multilayer.results import cycles, shear
from multilayer.results.folder import ResultsFolder
from multilayer.results.reading import lumen_field, read_series
from multilayer.runner.held import HeldResults
from multilayer.scene.setup import Setup
from multilayer.wall.stack import LUMEN

#: the pressure each open end's condition reports for its step (its mean normal stress), at z = 0 and z = L
END_PRESSURES = ("inlet", "outlet")


def _table(results: ResultsFolder | HeldResults, name: str) -> dict[str, np.ndarray]:
    if isinstance(results, HeldResults):
        return results.tables[name].arrays() if name in results.tables else {}
    return read_series(results.path / name)


def cycle_block(case: Case, setup: Setup, series: dict[str, np.ndarray]) -> dict[str, Any] | None:
    """The ``cycles`` block: the loads' period, the units, and :func:`multilayer.results.cycles.summarize` of the
    series; None when the loads do not repeat."""
    period = case.loads.period()
    if period is None or "t" not in series:
        return None
    pressures = {p.name: (p.z, series[p.name]) for p in case.output.probes if p.quantity == "p" and p.name in series}
    # the pulse-wave velocity from the pressure probes' feet (not the ends' step means), at two places or more
    waves = dict(pressures) if len({z for z, _ in pressures.values()}) > 1 else None
    for end, z in zip(END_PRESSURES, (0.0, case.geometry.length)):
        if f"end.{end}.p" in series:
            pressures[f"end.{end}.p"] = (z, series[f"end.{end}.p"])
    inflow = -series["end.inlet.Q"] if "end.inlet.Q" in series else None  # the column is the outward flux
    areas = {}
    if setup.wall is not None:
        R = case.geometry.radius
        areas = {p.name: (p.z, setup.geometry.section(R + series[p.name])) for p in case.output.probes
                 if p.quantity == "eta" and p.line == LUMEN and p.name in series}
    volume = setup.geometry.integral_units["flow_rate"].removesuffix("/s")
    units = {"pressure": "dyn/cm² (and mmHg)", "stroke_volume": "mL" if volume == "cm³" else f"{volume} per unit depth",
             "area": "cm²" if volume == "cm³" else "cm per unit depth", "distensibility": "cm²/dyn (and 1/mmHg)",
             "pulse_wave_velocity": "cm/s (and m/s)"}
    return {"period": period, "units": units,
            "cycles": cycles.summarize(series["t"], period, pressures, inflow, areas, waves=waves)}


def readouts(case: Case, setup: Setup | None, results: ResultsFolder | HeldResults) -> dict[str, Any]:
    """``cycles`` (with a periodic load) and ``wss`` (with a fluid that gives τ_w) for the summary."""
    if setup is None:
        return {}
    out: dict[str, Any] = {}
    block = cycle_block(case, setup, _table(results, "series.csv"))
    if block is not None:
        out["cycles"] = block
    table = _table(results, "wss_lumen.csv") if setup.gives_wall_shear else {}
    field = lumen_field(table, "wss_lumen.csv") if table else None
    if field is not None:
        z, t, wss = field
        start = 0.0
        if table["step"][0] > 1:  # a table begun after the run's start (a run resumed from an older checkpoint)
            t, wss, start = t[1:], wss[1:], float(t[0])
        out["wss"] = shear.summarize(t, z, wss, case.loads.period(), start)
    return out
