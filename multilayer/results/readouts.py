"""What a person reads of a run's probes: each quantity's unit, and its range in CGS and in the clinic's units.

Every number a run writes is CGS (cm, s, dyn/cm²).  Where a person reads
them — the line ``multilayer run`` ends with, ``summary.json``'s
``probe_ranges``, the figures' axes — pressures are given in mmHg too, and
a tube's flow rates in mL/s (= cm³/s).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from multilayer.plugin.units import MMHG

#: what each probe quantity is, and its CGS unit (a flow rate's: per unit depth; a tube's is cm³/s)
QUANTITIES = {
    "eta": ("η, radial wall displacement", "cm"),
    "v": ("v, radial wall velocity", "cm/s"),
    "d_z": ("d_z, axial wall displacement", "cm"),
    "d_r": ("d_r, radial wall displacement", "cm"),
    "u_z": ("u_z, axial fluid velocity", "cm/s"),
    "u_r": ("u_r, radial fluid velocity", "cm/s"),
    "p": ("p, pressure", "dyn/cm²"),
    "flow_rate": ("Q, flow rate", "cm²/s"),
}
#: the flow rate of a tube, in cm³/s, is in mL/s
TUBE_FLOW = "cm³/s"


def unit_of(quantity: str, units: Mapping[str, str] | None = None) -> str:
    """The CGS unit of a probe ``quantity``; ``units`` are the run's integral units (``summary.json`` ``units``:
    a tube's flow rate is cm³/s).

    >>> unit_of("p"), unit_of("flow_rate"), unit_of("flow_rate", {"flow_rate": "cm³/s"})
    ('dyn/cm²', 'cm²/s', 'cm³/s')
    """
    return (units or {}).get(quantity) or QUANTITIES.get(quantity, (quantity, ""))[1]


def probe_ranges(probes: Sequence[Mapping[str, Any]], series: Mapping[str, np.ndarray],
                 units: Mapping[str, str] | None = None) -> dict[str, dict[str, Any]]:
    """Each probe's ``quantity``, CGS ``unit``, ``min`` and ``max`` over the rows; a pressure's also in mmHg
    (``min_mmHg``, ``max_mmHg``), a tube's flow rate in mL/s (``min_mL_s``, ``max_mL_s``).  A probe without a
    finite value is left out.

    >>> round(probe_ranges([{"name": "p_in", "quantity": "p"}], {"p_in": np.array([1e5, 1.6e5])})["p_in"]["max_mmHg"], 3)
    120.01
    """
    out = {}
    for p in probes:
        values = np.asarray(series.get(p["name"], ()), dtype=float)
        values = values[np.isfinite(values)]
        if not values.size:
            continue
        unit = unit_of(p["quantity"], units)
        low, high = float(values.min()), float(values.max())
        entry = {"quantity": p["quantity"], "unit": unit, "min": low, "max": high}
        if p["quantity"] == "p":
            entry.update(min_mmHg=low / MMHG, max_mmHg=high / MMHG)
        elif p["quantity"] == "flow_rate" and unit == TUBE_FLOW:
            entry.update(min_mL_s=low, max_mL_s=high)
        out[p["name"]] = entry
    return out


def range_lines(ranges: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """The pressures (mmHg, then dyn/cm²) and flow rates (mL/s in a tube) of :func:`probe_ranges`, a line each.

    >>> print(*range_lines(probe_ranges([{"name": "p_in", "quantity": "p"}, {"name": "q", "quantity": "flow_rate"}],
    ...     {"p_in": np.array([MMHG * 80, MMHG * 120]), "q": np.array([-1.0, 6.0])}, {"flow_rate": "cm³/s"})), sep="\\n")
    p: p_in 80 to 120 mmHg (1.067e+05 to 1.6e+05 dyn/cm²)
    Q: q -1 to 6 mL/s
    """
    pressures = [f"{name} {e['min_mmHg']:.4g} to {e['max_mmHg']:.4g} mmHg ({e['min']:.4g} to {e['max']:.4g} dyn/cm²)"
                 for name, e in ranges.items() if e["quantity"] == "p"]
    flows = [f"{name} {e['min']:.4g} to {e['max']:.4g} {'mL/s' if e['unit'] == TUBE_FLOW else e['unit']}"
             for name, e in ranges.items() if e["quantity"] == "flow_rate"]
    return ([f"p: {', '.join(pressures)}"] if pressures else []) + ([f"Q: {', '.join(flows)}"] if flows else [])
