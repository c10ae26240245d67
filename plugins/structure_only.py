"""``structure-only``: the wall alone (no fluid), SCHEME §3 step A1 every step.

Loads: the external pressure P_e on the outer surface and a prescribed
pressure on the lumen line; or free vibration from initial profiles.
"""

from __future__ import annotations

from collections.abc import Iterator

from multilayer import ledger
from multilayer.hookspecs import hookimpl
from multilayer.interfaces import Coupler, StepReport
from multilayer.records import CouplerPlugin
from multilayer.structure import StructureStep


class StructureOnly(Coupler):
    name = "structure-only"
    loads = ("external", "interface")

    def check_case(self, case) -> list[str]:
        problems = super().check_case(case)
        if case.fluid is not None:
            problems.append("structure-only runs a wall without fluid: set fluid = \"none\", "
                            "or choose the coupler 'kinematic-splitting'")
        if not case.layers:
            problems.append("structure-only needs at least one layer in [[layers]]")
        return problems

    def evolve(self, scene) -> Iterator[StepReport]:
        wall, loads, dt = scene.wall, scene.case.loads, scene.dt
        step = StructureStep(scene.stack, dt, scene.stats, scene.case.solver)
        unit_outer = wall.line_load(wall.outer_line)
        unit_lumen = wall.line_load(0)
        previous = sum(step.energy(scene.wall_state).values())
        for n, t0, t1 in scene.windows():
            forces = {
                "external": -loads.external.average(t0, t1) * unit_outer,
                "interface": loads.interface.average(t0, t1) * unit_lumen,
            }
            scene.wall_state, energy, work, dissipation = step.step(scene.wall_state, forces)
            row = ledger.close(energy, previous, work, dissipation)
            previous = row["energy.total"]
            yield StepReport(n + 1, t1, row)


@hookimpl
def multilayer_couplers():
    return [CouplerPlugin(name="structure-only", factory=StructureOnly,
                          doc="The wall alone: all layers, backward Euler, factorized once.")]
