"""The wall step: every layer of the stack together, for any time scheme, factorized once.

The scheme (:mod:`multilayer.numerics.timescheme`) is applied to the wall's
first-order form, d' = V, M V' + C V + K d = F, and solved for the
test-level velocity V̄ = Σβ_k V^{n+1−k}:

    ((α₀/β₀) M/Δt + C + (β₀Δt/α₀) K) V̄ = F̄ − Σ_i M_i h_i/Δt − K d̄_old

(h_i the old levels of layer i's velocity, d̄_old the old displacements'
share of d̄).  With constant Δt this matrix never changes: it is factorized
at the first step and only back-substitution runs per step (adaptive steps
factorize it again when Δt changes).  For
backward Euler it is M/Δt² + C/Δt + K of theory §6 A1, scaled by Δt.

Each layer's inertia uses that layer's own old velocity: in a partitioned
coupled scheme the thin layer at the fluid interface gets vⁿ from the fluid
step, while a thick band keeps its Vⁿ, even at the DOFs they share; so a
Crank–Nicolson step ends with one new velocity per layer,
V_i^{n+1} = 2V̄ − V_iⁿ.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import attrs
import numpy as np
import scipy.sparse as sp

from multilayer.numerics.linsolve import SolverStats, factorize
from multilayer.numerics.timescheme import TimeScheme
from multilayer.scene.state import State, WallState
from multilayer.wall.stack import Stack


def _label(i: int) -> str:
    return f"layers[{i}]"


@attrs.frozen(eq=False)
class WallStep:
    """What one wall step produced: the new wall, the interface layer's new velocity, V̄, the energy terms."""

    wall: WallState
    v: np.ndarray | None  #: new velocity of the thin layer on the fluid line (line numbering)
    mean: np.ndarray  #: V̄, the test-level velocity (wall numbering)
    stored: dict[str, float]
    work: dict[str, float]
    dissipation: dict[str, float]


class StructureStep:
    """One step of the whole stack.

    Parameters
    ----------
    stack : Stack
        The assembled wall.
    scheme : TimeScheme
        The time discretization.
    dt : float
        Δt (s): the run's, or the first of adaptive steps (each step may pass its own).
    stats : SolverStats
        Where factorizations and solves are counted.
    backend : str
        A backend of :mod:`multilayer.numerics.linsolve`.
    fluid_line : int or None
        The line whose thin layers take their old velocity from ``State.v``
        (0 in a partitioned coupled run), or None when no fluid updates it.
    """

    def __init__(self, stack: Stack, scheme: TimeScheme, dt: float, stats: SolverStats,
                 backend: str = "superlu", fluid_line: int | None = None):
        self.stack = stack
        self.scheme = scheme
        self.dt = dt
        self.fluid_line = fluid_line
        self._stats, self._backend = stats, backend
        self._solver = None  # factorized at the first step: a monolithic solve uses only matrix() and rhs()
        self._solver_dt = dt  # the Δt of the factorized matrix

    def matrix(self, dt: float | None = None):
        """(α₀/β₀) M/Δt + C + (β₀Δt/α₀) K in the wall's numbering (every DOF), for Δt = ``dt`` (default: the run's)."""
        st, s, dt = self.stack, self.scheme, self.dt if dt is None else dt
        return st.mass * (s.inertia / dt) + st.damping + st.stiffness * s.displacement_gain(dt)

    # -- levels -----------------------------------------------------------------
    def own_velocity(self, index: int, state: State) -> np.ndarray:
        """The velocity layer ``index`` sees as its own in ``state`` (see :func:`own_velocity`)."""
        return own_velocity(self.stack, index, state, self.fluid_line)

    def rhs(self, states: Sequence[State], forces: Mapping[str, np.ndarray], dt: float | None = None) -> np.ndarray:
        """F̄ − Σ_i M_i h_i/Δt − K d̄_old for the old levels ``states`` (newest first)."""
        st, s, dt = self.stack, self.scheme, self.dt if dt is None else dt
        b = sum(forces.values(), np.zeros(st.space.ndofs))
        for i, m in enumerate(st.matrices):
            b = b - m.mass @ s.history([self.own_velocity(i, x) for x in states]) / dt
        return b - st.stiffness @ s.displacement_average_history([x.wall.d for x in states])

    def step(self, state: State, forces: Mapping[str, np.ndarray], dt: float | None = None) -> WallStep:
        """Advance by Δt (``dt``, default the run's) from ``state`` under ``forces`` (name → load vector F̄ in
        wall numbering).

        Returns the new wall and the terms of the step's energy identity
        (energy at the end of the step, work, dissipation).  A Δt other than
        the last step's changes the matrix: it is factorized again.
        """
        st, dt = self.stack, self.dt if dt is None else dt
        states = state.history(self.scheme.levels - 1)
        mean = np.zeros(st.space.ndofs)
        mean[st.free] = self._factors(dt).solve(self.rhs(states, forces, dt)[st.free])
        return self.finish(states, mean, forces, dt)

    def response(self, loads: sp.spmatrix, dt: float | None = None) -> np.ndarray:
        """The change of V̄ that each column of ``loads`` (wall numbering) makes as a force F̄ of a step of Δt.

        The step is linear in its forces, so a load F̄ + ΔF̄ moves V̄ by
        A⁻¹ΔF̄ with A = :meth:`matrix` on the free DOFs: one back-substitution
        per column of the factors :meth:`step` uses (a dense wall × column array).
        """
        st, dt = self.stack, self.dt if dt is None else dt
        out = np.zeros((st.space.ndofs, loads.shape[1]))
        out[st.free] = self._factors(dt).solve(loads.tocsr()[st.free].toarray())
        return out

    def _factors(self, dt: float):
        """The factorized matrix of Δt = ``dt``: factorized again when Δt changes."""
        if self._solver is None or self._solver_dt != dt:
            f = self.stack.free
            self._solver = factorize(self.matrix(dt).tocsr()[f][:, f], self._stats, self._backend)
            self._solver_dt = dt
        return self._solver

    def finish(self, states: Sequence[State], mean: np.ndarray, forces: Mapping[str, np.ndarray],
               dt: float | None = None) -> WallStep:
        """The new wall from V̄ solved (here or in a monolithic system), and the identity's terms."""
        st, s, dt = self.stack, self.scheme, self.dt if dt is None else dt
        d = s.displacement(mean, [x.wall.d for x in states], dt)
        V = s.new_level(mean, [x.wall.V for x in states])
        new_v = None
        if self.fluid_line is not None and states[0].v is not None:
            new_v = s.new_level(st.space.restrictions[self.fluid_line] @ mean, [x.v for x in states])
        new = State(states[0].n + 1, 0.0, WallState(d, V), v=new_v)
        stored, numerical, dissipation = {}, 0.0, {}
        ds = [d, *[x.wall.d for x in states]]
        for i, m in enumerate(st.matrices):
            vs = [self.own_velocity(i, new), *[self.own_velocity(i, x) for x in states]]
            stored[f"kinetic.{_label(i)}"] = s.stored(m.kinetic, vs)
            stored[f"elastic.{_label(i)}"] = s.stored(m.elastic, ds)
            dissipation[f"dissipation.viscous.{_label(i)}"] = m.dissipation(mean, dt)
            numerical += s.numerical(m.kinetic, vs) + s.numerical(m.elastic, ds)
        dissipation["dissipation.numerical.wall"] = numerical
        work = {f"work.{name}": dt * float(mean @ f) for name, f in forces.items()}
        return WallStep(WallState(d, V), new_v, mean, stored, work, dissipation)

    def energy(self, state: State) -> dict[str, float]:
        """Stored energy of every layer in ``state``, as the scheme measures it."""
        return wall_energy(self.stack, self.scheme, state, self.fluid_line)


def own_velocity(stack: Stack, index: int, state: State, fluid_line: int | None) -> np.ndarray:
    """The velocity layer ``index`` sees as its own in ``state`` (wall numbering).

    A thin layer on ``fluid_line`` moves with the fluid's trace ``state.v``
    when the state carries one; every other layer with the wall's V.
    """
    p = stack.space.placements[index]
    if state.v is not None and p.line is not None and p.line == fluid_line:
        return stack.space.prolongations[p.line] @ state.v
    return state.wall.V


def wall_energy(stack: Stack, scheme: TimeScheme, state: State, fluid_line: int | None = None) -> dict[str, float]:
    """Kinetic and elastic energy of every layer in ``state``, as ``scheme``'s identity measures it."""
    out = {}
    states = state.history(scheme.levels)
    for i, m in enumerate(stack.matrices):
        out[f"kinetic.{_label(i)}"] = scheme.stored(m.kinetic, [own_velocity(stack, i, x, fluid_line) for x in states])
        out[f"elastic.{_label(i)}"] = scheme.stored(m.elastic, [x.wall.d for x in states])
    return out


__all__ = ["StructureStep", "WallStep", "own_velocity", "wall_energy"]
