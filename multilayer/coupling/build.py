"""A case made ready to run: its coupler, and the setup built in the coupler's wall mode."""

from __future__ import annotations

import time

from multilayer.case.model import Case
from multilayer.coupling.contract import Coupler
from multilayer.plugin.registry import Registry
from multilayer.scene.setup import Setup, build_model


def prepare(case: Case, registry: Registry) -> tuple[Setup, Coupler]:
    """(setup, coupler) of ``case``: the coupler decides how the fluid sees the wall (its wall mode, its radial lines).

    The coupler's construction counts as assembly time, as the setup's does.
    """
    t0 = time.perf_counter()
    coupler = build_model(registry, "coupler", case.coupler)
    built = time.perf_counter() - t0
    setup = Setup.build(case, registry, coupler.fluid_wall(case), coupler.radial_lines(case),
                        coupler.fluid_interface_block(case))
    setup.timings["assembly"] += built
    return setup, coupler
