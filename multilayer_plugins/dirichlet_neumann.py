"""``dirichlet-neumann-explicit`` and ``dirichlet-neumann-implicit``: the classic partitioned couplers.

Each step, the fluid is solved with the wall's velocity as Dirichlet data on
Γ (ū_r = x), then the whole wall — the thin layer's inertia included — is
loaded by the fluid's force on it, the fluid's residual on the wall's u_r
rows (``Fluid.reaction``: with the conforming layout it is exact, no
traction is interpolated).  The wall answers with its velocity x̃ = V̄_Γ.

* explicit: one pass per step, x = the wall velocity extrapolated from the
  previous steps.  Unstable when the wall is light against the fluid it
  moves, ρ₁h/(ρ_f R) small (the added-mass effect, Causin, Gerbeau & Nobile
  2005): the run stops as failed when the energy outgrows the work put in.
* implicit: the fixed point x = x̃ is iterated to ``tolerance`` with Aitken
  relaxation or IQN-ILS (:mod:`multilayer.coupling.acceleration`), at most
  ``max_iterations`` times; the fluid matrix is factorized once per step
  (only its Dirichlet data change).  Iterations per step are reported.

On a thick first layer under ``lumen = "no-slip"`` the interface velocity
x stacks the lumen's (v_r, v_z): the fluid takes both as Dirichlet data, the
band both components of its force.

The domain of a step is explicit, predicted from the previous wall
velocities as in ``monolithic``.  Energy: the fluid's identity (with the
power of the prescribed wall velocity, Δt x·r) plus the wall's (with the
work of the fluid's force, −Δt x̃·r); they differ by Δt r·(x − x̃), the
energy the interface creates — zero for a converged implicit step up to the
tolerance — reported with the opposite sign as ``dissipation.interface``
(a term of the scheme, not work of a load).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from multilayer.coupling.acceleration import IQNILS, Aitken
from multilayer.coupling.contract import Coupler, SchemeFailure, StepReport
from multilayer.coupling.kit import (
    ThickLumen,
    axial_restriction,
    coupled_case_problems,
    external_force,
    flow_rate_ends,
    fluid_columns,
    fluid_domain,
    fluid_groups,
    lumen_param,
    predicted_domain,
    window_loads,
)
from multilayer.coupling.structure import StructureStep, wall_energy
from multilayer.numerics.timescheme import TimeScheme, scheme_param
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import CouplerPlugin, Param
from multilayer.scene.state import State
from multilayer.wall.stack import LUMEN

ACCELERATIONS = {"aitken": Aitken, "iqn-ils": IQNILS}


class DirichletNeumann(ThickLumen, Coupler):
    """Fluid with Dirichlet data on Γ, then the wall under the fluid's force; once, or iterated."""

    loads = ("inlet", "outlet", "external")
    implicit = False

    def check_case(self, case) -> list[str]:
        return super().check_case(case) + coupled_case_problems(self.name, case)

    def fluid_wall(self, case) -> str:
        return "prescribed"

    def energy(self, setup, state: State) -> dict[str, float]:
        return {**wall_energy(setup.stack, self.scheme, state), **setup.fluid.energy(state.fluid, *fluid_domain(state))}

    def accelerator(self):
        """The update of the interface velocity between iterations (implicit only)."""
        return None

    def evolve(self, setup, state: State) -> Iterator[tuple[State, StepReport]]:
        S, dt, fluid, wall = self.scheme, setup.dt, setup.fluid, setup.wall
        P, R = wall.prolongations[LUMEN], wall.restrictions[LUMEN]
        structure = StructureStep(setup.stack, S, dt, setup.stats("wall"), setup.case.solver, reuse=setup.case.reuse)
        ends = wall.lines[LUMEN].end_dofs
        # under no-slip the interface velocity x stacks the lumen's (v_r, v_z), and the fluid's force both components
        Rz = axial_restriction(setup) if self.no_slip(setup.case) else None
        if Rz is not None:
            ends = np.concatenate([ends, ends + R.shape[0]])
        accelerate = self.accelerator()
        if accelerate is not None:
            accelerate.recall(state.extra.get("acceleration"))
        for step, t0, t1 in setup.windows(state.n):
            loads = window_loads(setup, S, t0, t1)
            history = state.history(S.old_levels)
            prediction = predicted_domain(S, history, dt)
            x = prediction.velocity  # the wall velocity the fluid sees first
            if Rz is not None:
                x = np.concatenate([x, prediction.velocity_z])
            system = fluid.system([s.fluid for s in history], prediction.domain, S, dt, (t0, t1))
            if accelerate is not None:
                accelerate.start()
            iterations, residual = 0, 0.0
            while True:
                iterations += 1
                if Rz is None:
                    prescribed = fluid.prescribe(system, x)
                else:
                    prescribed = fluid.prescribe(system, *np.split(x, 2))
                solution = fluid.solve(prescribed)
                r = fluid.reaction(prescribed, solution.mean)  # minus the fluid's force on the wall
                force = P @ -r
                if Rz is not None:
                    force = force - Rz.T @ fluid.reaction(prescribed, solution.mean, axial=True)
                forces = {"external": external_force(setup, loads["external"]), "fluid": force}
                w = structure.step(state, forces)
                x_tilde = R @ w.mean if Rz is None else np.concatenate([R @ w.mean, Rz @ w.mean])
                change = x_tilde - x
                residual = float(np.linalg.norm(change) / max(np.linalg.norm(x_tilde), 1e-300))
                if accelerate is None or residual <= self.tolerance:
                    break
                if iterations >= self.max_iterations or not np.isfinite(residual):
                    raise SchemeFailure(
                        f"{self.name}: the interface iteration did not converge in {iterations} iterations at "
                        f"t = {t1:.6g} s (relative change {residual:.3g} > tolerance {self.tolerance:g}); "
                        f"the wall is too light for {self.acceleration}, or raise max_iterations")
                x = accelerate.next(x, x_tilde, change)
                x[ends] = 0.0
            eta_new = R @ w.wall.d
            extra = prediction.extra()
            if accelerate is not None:
                extra["acceleration"] = accelerate.memory()
            axial = None
            if Rz is not None:  # no-slip: the lumen's axial motion moves the domain too
                extra.update(eta_z=Rz @ w.wall.d, v_z=Rz @ w.wall.V)
                axial = (state.extra["eta_z"], extra["eta_z"])
            terms = fluid.identity(prescribed, solution, *prediction.identity_levels(state, eta_new, axial))
            state = state.then(S.old_levels, n=step + 1, t=t1, wall=w.wall, fluid=solution.state,
                               v=R @ w.wall.V, eta=eta_new, extra=extra)
            stored_f, work_f, dissipation_f = fluid_groups(terms)
            work = {k: v for k, v in {**w.work, **work_f}.items() if k not in ("work.fluid", "work.wall")}
            dissipation = {**w.dissipation, **dissipation_f,
                           "dissipation.interface": -(work_f["work.wall"] + w.work["work.fluid"])}
            yield state, StepReport({**w.stored, **stored_f}, work, dissipation,
                                    {"iterations": float(iterations), "interface.residual": residual,
                                     **fluid_columns(terms)}, alpha=S.alpha)


class DirichletNeumannExplicit(DirichletNeumann):
    name = "dirichlet-neumann-explicit"

    def check_case(self, case) -> list[str]:
        """Also refuses a flow-rate end: the prescribed inflow must leave at once through the other end."""
        return super().check_case(case) + [
            f"loads.{end} prescribes a flow rate, which {self.name} cannot take: its fluid step moves the wall with "
            "the wall's last velocity, so the prescribed inflow has no volume to fill and is forced through the "
            "other end in one step (the incompressibility dilemma of Dirichlet–Neumann coupling; on the carotid-like "
            "tube the energy outgrew the work at the first step); choose 'dirichlet-neumann-implicit', "
            "'kinematic-splitting' or 'monolithic'"
            for end in flow_rate_ends(case)]


class DirichletNeumannImplicit(DirichletNeumann):
    name = "dirichlet-neumann-implicit"
    implicit = True

    def __init__(self, scheme: TimeScheme | str = "backward-euler", acceleration: str = "iqn-ils",
                 tolerance: float = 1e-8, max_iterations: int = 500, relaxation: float = 0.5, reuse: int = 8,
                 lumen: str = "no-slip"):
        super().__init__(scheme, lumen)
        if acceleration not in ACCELERATIONS:
            raise ValueError(f"acceleration {acceleration!r} is not one of {', '.join(ACCELERATIONS)}")
        self.acceleration, self.tolerance, self.max_iterations = acceleration, tolerance, max_iterations
        self.relaxation, self.reuse = relaxation, reuse

    def accelerator(self):
        if self.acceleration == "aitken":
            return Aitken(self.relaxation)
        return IQNILS(self.relaxation, self.reuse)


@hookimpl
def multilayer_couplers():
    return [
        CouplerPlugin(name="dirichlet-neumann-explicit", factory=DirichletNeumannExplicit,
                      params=(scheme_param(), lumen_param()),
                      doc="Classic explicit partitioned coupling: fluid with the wall's velocity, then the wall "
                          "under the fluid's force; unstable for light walls."),
        CouplerPlugin(name="dirichlet-neumann-implicit", factory=DirichletNeumannImplicit,
                      params=(scheme_param(),
                              Param("acceleration", type=str, default="iqn-ils", choices=tuple(ACCELERATIONS),
                                    doc="update of the interface velocity between sub-iterations"),
                              Param("tolerance", default=1e-8, gt=0.0,
                                    doc="relative change of the interface velocity that ends the sub-iterations"),
                              Param("max_iterations", type=int, default=500, ge=1,
                                    doc="sub-iterations per step before the run stops as failed"),
                              Param("relaxation", "ω₀", default=0.5, gt=0.0, le=1.0,
                                    doc="relaxation of a step's first update (Aitken's start, IQN-ILS's first)"),
                              Param("reuse", type=int, default=8, ge=0,
                                    doc="IQN-ILS: time steps whose iterations are reused"),
                              lumen_param()),
                      doc="Dirichlet–Neumann sub-iterated to a tolerance with Aitken relaxation or IQN-ILS."),
    ]
