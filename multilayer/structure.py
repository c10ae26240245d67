"""SCHEME §3 step A1: all layers together, backward Euler, factorized once.

With constant Δt the matrix M/Δt² + C/Δt + K never changes, so it is
factorized when the step is built and only back-substitution runs per step.

Each layer's inertia uses that layer's own old velocity: in the coupled
scheme the thin layer at the fluid interface gets vⁿ from the fluid step,
while a thick band keeps its Vⁿ, even at the DOFs they share.
"""

from __future__ import annotations

from collections.abc import Mapping

import attrs
import numpy as np

from multilayer.linsolve import SolverStats, factorize
from multilayer.wall import Stack


@attrs.define(eq=False)
class WallState:
    """Wall displacement d, wall velocity V (wall numbering), and the velocity v
    of the thin layer on the fluid interface line when the fluid updates it."""

    d: np.ndarray
    V: np.ndarray
    v: np.ndarray | None = None

    def copy(self) -> WallState:
        return WallState(self.d.copy(), self.V.copy(), None if self.v is None else self.v.copy())


def _label(i: int) -> str:
    return f"layers[{i}]"


class StructureStep:
    """One backward-Euler step of the whole stack.

    Parameters
    ----------
    stack : Stack
        The assembled wall.
    dt : float
        Δt (s), constant over the run.
    stats : SolverStats
        Where factorizations and solves are counted.
    fluid_line : int or None
        The line whose thin layers take their old velocity from ``WallState.v``
        (0 in a coupled run), or None when no fluid updates it.
    """

    def __init__(self, stack: Stack, dt: float, stats: SolverStats, backend: str = "superlu",
                 fluid_line: int | None = None):
        self.stack = stack
        self.dt = dt
        self.fluid_line = fluid_line
        f = stack.free
        A = (stack.mass / dt**2 + stack.damping / dt + stack.stiffness).tocsr()
        self._A_free = A[f][:, f]
        self._solver = factorize(self._A_free, stats, backend)

    def own_velocity(self, index: int, state: WallState) -> np.ndarray:
        """The old velocity the layer ``index`` sees in its inertia term."""
        p = self.stack.space.placements[index]
        if state.v is not None and p.line is not None and p.line == self.fluid_line:
            return self.stack.space.prolongations[p.line] @ state.v
        return state.V

    def step(self, state: WallState, forces: Mapping[str, np.ndarray]) -> tuple[WallState, dict, dict, dict]:
        """Advance by Δt under ``forces`` (name → load vector in wall numbering).

        Returns the new state and the ledger groups (energy at n+½, work,
        dissipation) of SCHEME §4's A1 identity.
        """
        st, dt = self.stack, self.dt
        d0 = state.d
        inertia = st.mass @ d0 / dt**2 + st.damping @ d0 / dt
        for i, m in enumerate(st.matrices):
            inertia = inertia + m.mass @ self.own_velocity(i, state) / dt
        F = sum(forces.values(), np.zeros_like(d0))
        rhs = inertia + F
        d1 = np.zeros_like(d0)
        d1[st.free] = self._solver.solve(rhs[st.free])
        V1 = (d1 - d0) / dt
        new = WallState(d1, V1, None if state.v is None else st.space.prolongations[self.fluid_line].T @ V1)

        energy, dissipation = {}, {}
        dd = d1 - d0
        numerical = 0.0
        for i, m in enumerate(st.matrices):
            energy[f"kinetic.{_label(i)}"] = m.kinetic(V1)
            energy[f"elastic.{_label(i)}"] = m.elastic(d1)
            dissipation[f"dissipation.viscous.{_label(i)}"] = m.dissipation(V1, dt)
            numerical += m.kinetic(V1 - self.own_velocity(i, state)) + m.elastic(dd)
        dissipation["dissipation.numerical.A1"] = numerical
        work = {f"work.{name}": float(dd @ f) for name, f in forces.items()}
        return new, energy, work, dissipation

    def energy(self, state: WallState) -> dict[str, float]:
        """Stored energy of every layer in ``state``."""
        out = {}
        for i, m in enumerate(self.stack.matrices):
            out[f"kinetic.{_label(i)}"] = m.kinetic(self.own_velocity(i, state))
            out[f"elastic.{_label(i)}"] = m.elastic(state.d)
        return out


def zero_fixed(stack: Stack, x: np.ndarray) -> np.ndarray:
    """``x`` with the essential DOFs set to zero."""
    x = np.array(x, dtype=float)
    x[stack.fixed] = 0.0
    return x


__all__ = ["StructureStep", "WallState", "zero_fixed"]
