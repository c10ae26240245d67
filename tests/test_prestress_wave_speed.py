"""The pulse-wave speed rises with pressure in a prestressed HGO tube (issue 38's acceptance): the two bands of
Holzapfel, Gasser & Ogden (2000) (tests/test_prestress.py's tube, 8 cm long) imaged at R = 0.3 cm under P⁰ = 80
and 120 mmHg, prestressed, a small 10 ms pressure pulse (2 % of P⁰) in under monolithic TR-BDF2: the speed foot
to foot between the probes at z = 2 and 5 cm (multilayer.campaign.pulse_wave) against the Bramwell–Hill speed
√(A/(ρ dA/dP)) of the static pressure–area curve of the same prestressed wall at P⁰ ± 1 % (mid-way).

Measured (`pytest -s`, 24 × 2 cells, Δt = 2.5e-4): see the test's docstring.  On 32 cells along z the
reference folds at 120 mmHg next to the lumen's ends, which the fluid pins in their imaged place."""

import copy
import math

import numpy as np
import pytest
from test_prestress import MMHG, REGISTRY, TUBE

from multilayer.case.casefile import validate_data
from multilayer.coupling.build import prepare
from multilayer.results.pulse import foot_to_foot
from multilayer.results.reading import read_run
from multilayer.runner.loop import run_case
from multilayer.wall.equilibrium import static_deflection
from multilayer.wall.stack import LUMEN

LENGTH, DURATION, PROBES = 8.0, 0.01, (2.0, 5.0)


def speeds(tmp_path, mmhg: float) -> tuple[float, float]:
    """(foot-to-foot on the pressure at the axis, Bramwell–Hill) in cm/s at P⁰ = ``mmhg``."""
    P0 = mmhg * MMHG
    data = copy.deepcopy(TUBE)
    data["geometry"]["length"] = LENGTH
    data["mesh"] = {"nz": 24, "nr": 2, "order": 2}
    data["layers"][0]["cells"] = 1
    data["initial"]["pressure"] = P0
    data["coupler"] = {"model": "monolithic", "scheme": "tr-bdf2"}
    data["time"] = {"end": 0.016, "dt": 2.5e-4}
    data["loads"] = {"inlet": f"{P0} + {0.02 * P0}*(1 - cos(2*pi*t/{DURATION}))/2*(t < {DURATION})", "outlet": P0}
    data["output"] = {"probes": [{"name": f"p_{z:g}", "quantity": "p", "z": z, "r": 0.0} for z in PROBES]}
    case = validate_data(data, tmp_path, REGISTRY)
    out = tmp_path / f"run{mmhg:g}"
    result = run_case(case, out, REGISTRY)
    assert result.status == "ok", result.reason
    run = read_run(out.name, out)
    speed, _ = foot_to_foot([(f"p_{z:g}", z, np.asarray(run.t), np.asarray(run.series[f"p_{z:g}"])) for z in PROBES])
    assert speed.value is not None, speed
    stack = prepare(case, REGISTRY)[0].stack  # the wall on its reference, as the run had it
    mid = int(np.argmin(np.abs(stack.space.lines[LUMEN].z - LENGTH / 2)))

    def area(P):
        eta = (stack.space.restrictions[LUMEN] @ static_deflection(stack, P, 0.0, tolerance=1e-10))[mid]
        return math.pi * (0.3 + eta) ** 2

    dP = 0.01 * P0
    compliance = (area(P0 + dP) - area(P0 - dP)) / (2.0 * dP)
    return speed.value, math.sqrt(area(P0) / (TUBE["fluid"]["density"] * compliance))


@pytest.mark.slow
def test_the_wave_speed_rises_with_pressure_as_bramwell_hill_says(tmp_path):
    """Within 3 % of Bramwell–Hill at 80 and 120 mmHg, and faster at 120.

    Measured (24 × 2 cells): 80 mmHg 603.7 cm/s foot to foot, Bramwell–Hill 590.4 (+2.2 %); 120 mmHg 788.9
    against 766.5 (+2.9 %); at 80 mmHg on 32 × 2 cells 602.1 against 592.5 (+1.6 %): the excess falls with the
    mesh along z.  The reference is found once a pressure, by validation: the run and the static curve take it
    from the case."""
    found = {mmhg: speeds(tmp_path, mmhg) for mmhg in (80.0, 120.0)}
    for mmhg, (measured, bramwell_hill) in found.items():
        print(f"{mmhg:g} mmHg: foot to foot {measured:.1f} cm/s, Bramwell–Hill {bramwell_hill:.1f} cm/s "
              f"({measured / bramwell_hill - 1:+.1%})")
        assert abs(measured / bramwell_hill - 1.0) <= 0.03
    assert found[120.0][0] > 1.2 * found[80.0][0]
