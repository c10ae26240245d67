"""multilayer: fluid–multi-layered-structure interaction.

Incompressible flow in a 2D compliant channel coupled, by the kinematically
coupled scheme, to a wall made of a stack of thin and thick layers.  Every
model (layer, fluid, coupler) is a pluggy plugin; scenes are TOML case files.

The Python API (:mod:`multilayer.api`, ``docs/python-api.md``)::

    import multilayer as ml

    case = ml.load_case("cases/pulse-koiter-thick.toml", {"time.end": 0.004})
    res = ml.run(case)                        # or ml.run(case, "results/pulse") for a results folder
    print(res.status, res.peaks, res.max_relative_residual)
"""

from multilayer.api import (
    Case,
    CaseError,
    Results,
    RunFailed,
    Step,
    load_case,
    read_results,
    run,
    steps,
)
from multilayer.version import __version__

__all__ = [
    "Case",
    "CaseError",
    "Results",
    "RunFailed",
    "Step",
    "__version__",
    "load_case",
    "read_results",
    "run",
    "steps",
]
