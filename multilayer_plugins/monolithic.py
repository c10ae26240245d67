"""``monolithic``: the fluid and every layer of the wall in one linear system per step.

The conforming layout (theory §3) makes this a sum: the thin layer's DOFs
are the fluid's u_r DOFs on Γ, so adding the wall's equations to the
fluid's on those rows (test functions q = ψ e_r) cancels the interface
traction exactly; no traction is ever computed.  Both are solved for the
scheme's test-level unknowns (ū, p̄, V̄) with ū_r = V̄ on Γ, so the
kinematic condition holds at every level.

The geometry is explicit: the domain of each step is predicted from the
previous wall motion (:func:`multilayer.coupling.kit.predicted_domain`),
vⁿ for backward Euler, the linear extrapolation to the evaluation time for
BDF2 and, for Crank–Nicolson, of the displacement's midpoint quotients,
which its undamped mode (−1)ⁿ does not reach.  The energy identity is the
sum of the wall's and the fluid's; what the predicted domain misses of the
true one is the fluid's geometric remainder (``dissipation.geometric.fluid``),
except under Crank–Nicolson, which damps nothing to cover it: there the
fluid lives on its own domains, the predicted ones, and keeps only the
scheme's own remainder (theory §6).  No splitting error: this is the
accuracy reference of the project, and its cost anchor.

On a thick first layer under ``lumen = "no-slip"`` the band's d_z DOFs on
the lumen are the fluid's wall u_z unknowns as well (the fluid's wall mode
``no-slip``), and the domain follows the lumen's axial motion.

With a scheme that estimates its error (Crank–Nicolson, BDF2) it takes adaptive steps (``[time] tolerance``,
:mod:`multilayer.coupling.clock`): a new Δt changes the wall's share of the
matrix (its pattern stays), the extrapolations see the step ratio, and so do
variable-step BDF2's coefficients (a new ratio at the same Δt changes α₀).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import scipy.sparse as sp

from multilayer.coupling.clock import Window, march
from multilayer.coupling.contract import Coupler, StepReport
from multilayer.coupling.kit import (
    ThickLumen,
    axial_restriction,
    coupled_case_problems,
    external_force,
    fluid_domain,
    joint_report,
    lumen_param,
    predicted_domain,
    window_loads,
)
from multilayer.coupling.structure import StructureStep, wall_energy
from multilayer.numerics.assembly.pattern import Pattern
from multilayer.numerics.linsolve import LowRank, ReusingSolver
from multilayer.numerics.newton import CHORD, newton
from multilayer.numerics.timescheme import scheme_param
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import CouplerPlugin
from multilayer.scene.state import State
from multilayer.wall.stack import LUMEN


class Monolithic(ThickLumen, Coupler):
    name = "monolithic"
    loads = ("inlet", "outlet", "external")
    adaptive = True
    multistage = True

    def check_case(self, case) -> list[str]:
        return super().check_case(case) + coupled_case_problems(self.name, case)

    def fluid_wall(self, case) -> str:
        """``no-slip`` for a fluid on a thick first layer under ``lumen = "no-slip"``: u_z is shared too."""
        return "no-slip" if self.no_slip(case) else "coupled"

    def energy(self, setup, state: State) -> dict[str, float]:
        return {**wall_energy(setup.stack, self.scheme, state), **setup.fluid.energy(state.fluid, *fluid_domain(state))}

    def numbering(self, setup) -> np.ndarray:
        """The unknown of the monolithic system of each wall DOF.

        The fluid's unknowns come first; a wall DOF on the lumen line's radial
        component is the fluid's wall u_r there (and under no-slip its axial
        one the fluid's wall u_z), every other wall DOF follows.
        """
        wall, fluid = setup.wall, setup.fluid
        nf = fluid.ndofs
        glob = np.full(wall.ndofs, -1, dtype=np.int64)
        glob[wall.line_dofs(LUMEN)] = fluid.interface_dofs
        if self.no_slip(setup.case):
            glob[wall.line_z_dofs(LUMEN)] = fluid.interface_z_dofs
        rest = np.flatnonzero(glob < 0)
        glob[rest] = nf + np.arange(rest.size)
        return glob

    def evolve(self, setup, state: State) -> Iterator[tuple[State, StepReport]]:
        fluid, wall, stack = setup.fluid, setup.wall, setup.stack
        R = wall.restrictions[LUMEN]
        wall_stats = setup.stats("wall")
        Rz = axial_restriction(setup) if self.no_slip(setup.case) else None
        glob = self.numbering(setup)
        n = fluid.ndofs + int(np.count_nonzero(glob >= fluid.ndofs))
        solver = ReusingSolver(setup.stats("monolithic"), setup.case.solver, setup.case.reuse)
        held: dict = {"key": None, "wall": None, "layout": None}  # a linear wall's matrix of the last Δt and α,
        # the system's layout

        def advance(state: State, w: Window) -> tuple[State, StepReport]:
            S, dt, t0, t1 = w.scheme, w.dt, w.t0, w.t1
            structure = StructureStep(stack, S, dt, wall_stats)  # S: the step's ratio (BDF2's α)
            if stack.linear and held["key"] != (dt, S.alpha):  # adaptive steps: the wall's matrix changes, its
                held["key"], held["wall"] = (dt, S.alpha), sp.coo_matrix(structure.matrix(dt))  # pattern does not
            loads = window_loads(setup, S, t0, t1)
            history = state.history(S.old_levels)
            prediction = predicted_domain(S, history, dt)
            system = fluid.system([x.fluid for x in history], prediction.domain, S, dt, (t0, t1))
            A_f, b_f, fixed_f, values_f = fluid.matrix(system)
            forces = {"external": external_force(setup, loads["external"])}
            x = np.zeros(n)
            x[fixed_f] = values_f
            fixed = np.concatenate([fixed_f, glob[stack.fixed]])

            last: dict = {}  # the latest matrix and the unknowns it is at: the start's is the first correction's

            def matrix(free_x):
                """The system's matrix with the wall's tangent at ``free_x`` (its constant matrix when linear), and
                the low-rank part of that tangent on the free unknowns (None when it has none)."""
                at = unknowns(free_x) if held["layout"] is not None else None
                if at is not None and "at" in last and np.array_equal(last["at"], at):
                    return last["out"]
                A_wall, update = held["wall"], None
                if not stack.linear:
                    A_wall, update = structure.jacobian(history, unknowns(free_x)[glob], dt)
                    A_wall = sp.coo_matrix(A_wall)
                layout = held["layout"]
                if layout is None or not layout.fits(A_f, A_wall):
                    layout = held["layout"] = Layout(A_f, A_wall, glob, fixed, n)
                if update is not None:  # the wall's numbering into the system's (glob is one-to-one)
                    U, W = np.zeros((n, update.U.shape[1])), np.zeros((n, update.U.shape[1]))
                    U[glob], W[glob] = update.U, update.W
                    update = LowRank(U[layout.free], W[layout.free])
                out = layout, layout.fill(A_f.data, A_wall.data), update
                last["at"], last["out"] = unknowns(free_x), out
                return out

            def unknowns(free_x):
                """The system's unknowns: the fixed values, and ``free_x`` on the free ones (None: zero)."""
                out = x.copy()
                if free_x is not None:
                    out[held["layout"].free] = free_x
                return out

            layout, data, _ = matrix(None)  # (a nonlinear wall's tangent at the start)
            if stack.linear:  # the first correction from zero: the linear system's solution
                b = np.zeros(n)
                b[: fluid.ndofs] = b_f
                np.add.at(b, glob, structure.rhs(history, forces, dt))
                rhs = b[layout.free] - layout.free_fixed.matrix(data) @ x[layout.fixed]
                result = newton(None, lambda _, r: solver.solve(layout.free_free.matrix(data, keep=True), r), None,
                                linear=True, first=rhs)
            else:
                magnitude = abs(A_f)

                def residual(free_x):
                    """The fluid's rows b_f − A_f x and the wall's out-of-balance force, summed on the shared rows."""
                    full = unknowns(free_x)
                    xf = full[: fluid.ndofs]
                    r, size = np.zeros(n), np.zeros(n)
                    r[: fluid.ndofs] = b_f - A_f @ xf
                    size[: fluid.ndofs] = np.abs(b_f) + magnitude @ np.abs(xf)
                    r_wall, size_wall = structure.residual(history, forces, full[glob], dt)
                    np.add.at(r, glob, r_wall)
                    np.add.at(size, glob, size_wall)
                    return r[held["layout"].free], size[held["layout"].free]

                def solve(free_x, r):
                    out = matrix(free_x)
                    layout, data, update = out
                    # (``out`` stands for the matrix: one held by the chord iteration is solved again, its own
                    # factorization taken at its second solve)
                    return solver.solve(layout.free_free.matrix(data, keep=True), r, key=out, update=update,
                                        lasting=CHORD is not None)

                result = newton(residual, solve, np.zeros(layout.free.size), stats=solver.stats,
                                what="the monolithic system", chord=CHORD)
            x = unknowns(result.x)
            # each part takes back its share of the solution
            solution = fluid.advance(system, x[: fluid.ndofs])
            wstep = structure.finish(history, x[glob], forces, dt, result)
            eta_new = R @ wstep.wall.d
            axial, extra = None, prediction.carried(state.extra)
            if Rz is not None:  # no-slip: the lumen's axial motion moves the domain too
                extra.update(eta_z=Rz @ wstep.wall.d, v_z=Rz @ wstep.wall.V)
                axial = (state.extra["eta_z"], extra["eta_z"])
            terms = fluid.identity(system, solution, *prediction.identity_levels(state, eta_new, axial))
            new = state.then(S.old_levels, n=w.n + 1, t=t1, wall=wstep.wall, fluid=solution.state,
                             v=fluid.wall_velocity(solution.state), eta=eta_new, extra=extra)
            return new, joint_report(wstep, terms)

        return march(setup, self.scheme, state, advance)


class Layout:
    """The monolithic system's sparsity, fixed for the run: the fluid's pattern and the wall's, summed.

    A step fills it with the pattern's filler (``np.add.at``) and takes the free/fixed blocks as
    index maps (:class:`multilayer.numerics.assembly.pattern.Pattern`), like the fluid's own step.
    """

    def __init__(self, A_f: sp.csr_matrix, A_wall: sp.coo_matrix, glob: np.ndarray, fixed: np.ndarray, n: int):
        self.indptr, self.indices = A_f.indptr.copy(), A_f.indices.copy()  # the fluid's pattern
        self.wall = (A_wall, A_wall.row.copy(), A_wall.col.copy())  # the wall's
        f = A_f.tocoo()
        fluid_entries = (f.row.astype(np.int64), f.col.astype(np.int64))
        wall_entries = (glob[A_wall.row], glob[A_wall.col])
        self.pattern = Pattern((n, n), [fluid_entries, wall_entries])
        self.fill = self.pattern.filler([self.pattern.slots(*fluid_entries), self.pattern.slots(*wall_entries)])
        self.fixed = np.unique(fixed)
        self.free = np.setdiff1d(np.arange(n), self.fixed)
        self.free_free = self.pattern.block(self.free, self.free)
        self.free_fixed = self.pattern.block(self.free, self.fixed)

    def fits(self, A_f: sp.csr_matrix, A_wall: sp.coo_matrix) -> bool:
        """True when the fluid's and the wall's matrices still have the patterns this layout was built for."""
        wall = A_wall is self.wall[0] or (np.array_equal(A_wall.row, self.wall[1])
                                          and np.array_equal(A_wall.col, self.wall[2]))
        return wall and np.array_equal(A_f.indptr, self.indptr) and np.array_equal(A_f.indices, self.indices)


@hookimpl
def multilayer_couplers():
    return [CouplerPlugin(name="monolithic", factory=Monolithic, params=(scheme_param(), lumen_param()),
                          doc="Fluid and wall in one linear system per step (geometry explicit); the accuracy "
                              "reference.")]
