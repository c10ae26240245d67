"""``structure-only``: the wall alone (no fluid), every layer of the stack, every step.

Loads: the external pressure P_e on the outer surface and a prescribed
pressure on the lumen line; or free vibration from initial profiles.  Any
scheme of :mod:`multilayer.numerics.timescheme` (a multi-stage one stage by stage:
:func:`multilayer.coupling.clock.march`); the matrix is factorized once (once per distinct matrix of the
stages: TR-BDF2's two share one).
"""

from __future__ import annotations

from collections.abc import Iterator

from multilayer.coupling.clock import Window, march
from multilayer.coupling.contract import Coupler, StepReport
from multilayer.coupling.kit import external_force, window_loads
from multilayer.coupling.structure import StructureStep, wall_energy
from multilayer.numerics.timescheme import scheme_param
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import CouplerPlugin
from multilayer.scene.state import State


class StructureOnly(Coupler):
    name = "structure-only"
    loads = ("external", "interface")
    multistage = True

    def check_case(self, case) -> list[str]:
        problems = super().check_case(case)
        if case.fluid is not None:
            problems.append("structure-only runs a wall without fluid: set fluid = \"none\", "
                            "or choose the coupler 'kinematic-splitting'")
        if not case.layers:
            problems.append("structure-only needs at least one layer in [[layers]]")
        return problems

    def energy(self, setup, state: State) -> dict[str, float]:
        return wall_energy(setup.stack, self.scheme, state)

    def evolve(self, setup, state: State) -> Iterator[tuple[State, StepReport]]:
        structure = StructureStep(setup.stack, self.scheme, setup.dt, setup.stats("wall"), setup.case.solver,
                                  reuse=setup.case.reuse)
        unit_lumen = setup.wall.line_load(0)

        def advance(state: State, w: Window) -> tuple[State, StepReport]:
            S = w.scheme
            loads = window_loads(setup, S, w.t0, w.t1)
            forces = {"external": external_force(setup, loads["external"]),
                      "interface": loads["interface"] * unit_lumen}
            a = structure.using(S).step(state, forces, w.dt)  # a stage's scheme: the factors of its matrix shared
            return state.then(S.old_levels, n=w.n + 1, t=w.t1, wall=a.wall), StepReport(a.stored, a.work,
                                                                                         a.dissipation)

        return march(setup, self.scheme, state, advance)


@hookimpl
def multilayer_couplers():
    return [CouplerPlugin(name="structure-only", factory=StructureOnly, params=(scheme_param(),),
                          doc="The wall alone: all layers, any time scheme, factorized once.")]
