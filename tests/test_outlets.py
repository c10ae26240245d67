"""The bundled outlet cases: a matched resistance absorbs the pulse, an RCR outlet reaches a periodic state.

The reflected wave is measured as a run minus a reference run in a channel
twice as long, whose own outlet reflection cannot come back to the probe
before the end: what is left is what the outlet sent back.
"""

import numpy as np
from runs import run_case_file


def run(tmp_path, case, *sets):
    result, data = run_case_file(case, tmp_path, *sets)
    assert result.status == "ok", result.reason
    return data.series


def test_a_resistance_matched_to_the_impedance_absorbs_the_pulse(tmp_path):
    """Measured at 30 cells along z (the case has 60; docs/boundary-conditions.md, "Absorption"): the wave
    reflected back to z = 3 cm is 7.3 % of the one p_out = 0 reflects, at z = 1 cm 3.4 %."""
    coarse = ("mesh.nz=30",)
    matched = run(tmp_path / "matched", "pulse-resistance", *coarse)
    free = run(tmp_path / "free", "pulse-resistance", *coarse, "loads.outlet=0.0")
    long = run(tmp_path / "long", "pulse-resistance", "geometry.length=12.0", "mesh.nz=60")
    for probe in ("p_z3", "p_z1"):
        reflected = np.max(np.abs(matched[probe] - long[probe]))
        assert reflected <= 0.10 * np.max(np.abs(free[probe] - long[probe])), probe
    # before the reflection comes back the runs see the same incident wave, up to what an incompressible fluid
    # feels of its outlet at once (measured 1.5e-4 of the peak up to t = 12 ms)
    early = matched["t"] <= 0.012
    assert np.allclose(matched["p_z3"][early], long["p_z3"][early], atol=1e-3 * np.max(np.abs(long["p_z3"])))
    assert np.all(matched["energy.relative_residual"] <= 1e-9)


def test_an_rcr_outlet_reaches_a_periodic_state(tmp_path):
    """Measured: the outlet pressure changes by 46 %, 0.23 % and 0.083 % from cycle to cycle (a run from P_c⁰ near
    the periodic mean), and the mean inflow and outflow of the last cycle agree (mass stored in the wall
    returns each cycle)."""
    s = run(tmp_path / "rcr", "physiological-rcr")
    n = 400  # steps a cycle
    p = s["end.outlet.p"]
    last, before = p[-n:], p[-2 * n:-n]
    assert np.max(np.abs(last - before)) < 0.01 * np.max(np.abs(last))
    q_in, q_out = -s["end.inlet.Q"][-n:].mean(), s["end.outlet.Q"][-n:].mean()
    assert abs(q_in - q_out) < 0.01 * abs(q_out)
    assert np.all(s["energy.relative_residual"] <= 1e-9)
