"""``fluid-only``: the fluid in a channel whose wall is rigid or moves as prescribed.

No wall model: with ``loads.wall_motion`` unset the wall is rigid (u = 0 on
it); with a formula η(t, z) the channel moves with it and the fluid sees
u = ∂_t η e_r on the wall.  This scene tests the ALE machinery on its own.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from multilayer import ledger
from multilayer.hookspecs import hookimpl
from multilayer.interfaces import Coupler, StepReport
from multilayer.records import CouplerPlugin
from multilayer_plugins.channel.ledger import ledger_groups
from multilayer_plugins.channel.model import wall_motion


class FluidOnly(Coupler):
    name = "fluid-only"
    loads = ("inlet", "outlet")

    def check_case(self, case) -> list[str]:
        problems = super().check_case(case)
        if case.fluid is None:
            problems.append("fluid-only needs a fluid: set [fluid] model = \"navier-stokes\" or \"stokes\"")
        if case.layers:
            problems.append("fluid-only has a rigid or prescribed wall and no wall layers: remove [[layers]], "
                            "or choose the coupler 'kinematic-splitting'")
        return problems

    def prepare(self, scene) -> None:
        motion = scene.case.loads.wall_motion
        scene.setup_fluid("prescribed" if motion is not None else "rigid")
        if motion is not None:
            scene.fluid_eta = np.asarray(motion(t=0.0, z=scene.fluid.line.z), dtype=float)

    def evolve(self, scene) -> Iterator[StepReport]:
        case, fluid, dt = scene.case, scene.fluid, scene.dt
        motion = case.loads.wall_motion
        line = fluid.line
        eta_of = (lambda t, z: motion(t=t, z=z)) if motion is not None else None
        previous = fluid.kinetic_energy(scene.fluid_state, scene.fluid_eta)
        for n, t0, t1 in scene.windows():
            if motion is not None:
                eta_n, v_half = wall_motion(line, eta_of, t0, dt)
            else:
                eta_n = v_half = None
            res = fluid.step(scene.fluid_state, eta_n, v_half,
                             case.loads.inlet.average(t0, t1), case.loads.outlet.average(t0, t1))
            scene.fluid_state = res.state
            if motion is not None:
                scene.fluid_eta = eta_n + dt * v_half
            stored, work, dissipation = ledger_groups(res.energy)
            if motion is not None:
                work["work.wall"] = res.energy["wall.work"]
            row = ledger.close(stored, previous, work, dissipation)
            previous = row["energy.total"]
            yield StepReport(n + 1, t1, row)


@hookimpl
def multilayer_couplers():
    return [CouplerPlugin(name="fluid-only", factory=FluidOnly,
                          doc="The fluid alone: rigid wall, or a wall moved by loads.wall_motion.")]
