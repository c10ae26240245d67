"""``fluid-only``: the fluid in a channel whose wall is rigid or moves as prescribed.

No wall model: with ``loads.wall_motion`` unset the wall is rigid (u = 0 on
it); with a formula η(t, z) the channel moves with it and the fluid sees
ū_r = (Σα_k η^{n+1−k})/Δt on the wall, the velocity the scheme integrates
to the prescribed η.  This scene tests the ALE machinery on its own.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from multilayer.coupling.clock import Window, march
from multilayer.coupling.contract import Coupler, StepReport
from multilayer.coupling.kit import fluid_columns, fluid_groups
from multilayer.fluid.contract import Domain
from multilayer.numerics.timescheme import scheme_param
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import CouplerPlugin
from multilayer.scene.state import State


class FluidOnly(Coupler):
    name = "fluid-only"
    loads = ("inlet", "outlet")
    multistage = True

    def check_case(self, case) -> list[str]:
        problems = super().check_case(case)
        if case.fluid is None:
            problems.append("fluid-only needs a fluid: set [fluid] model = \"navier-stokes\" or \"stokes\"")
        if case.layers:
            problems.append("fluid-only has a rigid or prescribed wall and no wall layers: remove [[layers]], "
                            "or choose the coupler 'kinematic-splitting'")
        return problems

    def fluid_wall(self, case) -> str:
        return "prescribed" if case.loads.wall_motion is not None else "rigid"

    def initial_state(self, setup) -> State:
        state = setup.initial_state()
        if setup.case.loads.wall_motion is not None:
            state = State(0, 0.0, fluid=state.fluid, eta=self._eta(setup, 0.0))
        return state

    @staticmethod
    def _eta(setup, t: float) -> np.ndarray:
        line = setup.fluid.line
        return np.asarray(setup.case.loads.wall_motion(t=t, z=line.z), dtype=float) * np.ones(line.ndofs)

    def energy(self, setup, state: State) -> dict[str, float]:
        return {**setup.fluid.energy(state.fluid, state.eta)}

    def evolve(self, setup, state: State) -> Iterator[tuple[State, StepReport]]:
        fluid = setup.fluid
        moving = setup.case.loads.wall_motion is not None
        still = Domain.still(fluid.line.ndofs)

        def advance(state: State, w: Window) -> tuple[State, StepReport]:
            S, dt = w.scheme, w.dt
            history = state.history(S.old_levels)
            if moving:
                etas = [self._eta(setup, w.t1), *[x.eta for x in history]]
                domain = Domain(S.geometry(etas), S.difference(etas) / dt)
            else:
                etas, domain = [still.eta, still.eta], still
            sol, f = fluid.step([x.fluid for x in history], domain, S, dt, (w.t0, w.t1),
                                eta_old=etas[1], eta_new=etas[0])
            stored, work, dissipation = fluid_groups(f)
            return state.then(S.old_levels, n=w.n + 1, t=w.t1, fluid=sol.state, eta=etas[0]), StepReport(
                stored, work, dissipation, {"energy.relative_residual.A2": abs(f["a2.residual"]) / f["a2.scale"],
                                            **fluid_columns(f)}, alpha=S.alpha)

        return march(setup, self.scheme, state, advance)


@hookimpl
def multilayer_couplers():
    return [CouplerPlugin(name="fluid-only", factory=FluidOnly, params=(scheme_param(),),
                          doc="The fluid alone: rigid wall, or a wall moved by loads.wall_motion.")]
