"""A scene: the case's models built and placed, ready for a coupler to drive.

The scene owns what every coupler shares: the layer objects, the wall's
spaces and assembled stack, the fluid (if any), the current state, the
solver statistics and the phase timings.  It also evaluates probes and
writes field snapshots, so couplers only advance the state.
"""

from __future__ import annotations

import time
from typing import Any

import attrs
import numpy as np

from multilayer.case import Case, Probe
from multilayer.interfaces import Coupler, Fluid, Layer
from multilayer.linsolve import SolverStats
from multilayer.registry import Registry
from multilayer.structure import WallState, zero_fixed
from multilayer.wall import LUMEN, Stack, WallSpace

def build_model(registry: Registry, kind: str, spec) -> Any:
    return registry.get(kind, spec.model).record.factory(**dict(spec.params))


@attrs.define(eq=False)
class Scene:
    case: Case
    registry: Registry
    layers: list[Layer]
    coupler: Coupler
    fluid: Fluid | None = None
    wall: WallSpace | None = None
    stack: Stack | None = None
    wall_state: WallState | None = None
    fluid_state: Any = None
    fluid_eta: np.ndarray | None = None  #: η of the fluid's current domain, on the fluid's line
    stats: SolverStats = attrs.field(factory=SolverStats)
    timings: dict[str, float] = attrs.field(factory=lambda: {"assembly": 0.0, "output": 0.0})

    @classmethod
    def build(cls, case: Case, registry: Registry) -> Scene:
        t0 = time.perf_counter()
        layers = [build_model(registry, "layer", spec) for spec in case.layers]
        coupler = build_model(registry, "coupler", case.coupler)
        fluid = build_model(registry, "fluid", case.fluid) if case.fluid is not None else None
        scene = cls(case=case, registry=registry, layers=layers, coupler=coupler, fluid=fluid)
        if layers:
            g, m = case.geometry, case.mesh
            scene.wall = WallSpace.build(layers, g.length, g.radius, m.nz, m.order,
                                         [spec.cells for spec in case.layers])
            scene.stack = Stack.assemble(scene.wall)
            init = case.initial
            d0 = scene.wall.interpolate(init.displacement_z, init.displacement_r)
            v0 = scene.wall.interpolate(init.velocity_z, init.velocity_r)
            scene.wall_state = WallState(zero_fixed(scene.stack, d0), zero_fixed(scene.stack, v0))
        scene.timings["assembly"] += time.perf_counter() - t0
        return scene

    def setup_fluid(self, wall_mode: str) -> None:
        """Discretize the fluid for ``wall_mode`` (``coupled``, ``rigid``, ``prescribed``) and start it at rest."""
        t0 = time.perf_counter()
        g, m = self.case.geometry, self.case.mesh
        line = self.wall.lines[LUMEN] if self.wall is not None else None
        self.fluid.setup(g.length, g.radius, m.nz, m.nr, m.order, m.grading, self.dt, wall_mode,
                         self.case.solver, line=line)
        self.fluid_state = self.fluid.initial_state()
        self.fluid_eta = np.zeros(self.fluid.line.ndofs)
        self.timings["assembly"] += time.perf_counter() - t0

    @property
    def dt(self) -> float:
        return self.case.time.dt

    @property
    def steps(self) -> int:
        return self.case.time.steps

    def windows(self):
        """(n, tⁿ, tⁿ⁺¹) for every step of the run."""
        dt = self.dt
        for n in range(self.steps):
            yield n, n * dt, (n + 1) * dt

    # -- wall quantities ----------------------------------------------------
    def eta(self, line: int = LUMEN) -> np.ndarray:
        """η on ``line`` in the line's own numbering."""
        return self.wall.prolongations[line].T @ self.wall_state.d

    def wall_velocity(self, line: int = LUMEN) -> np.ndarray:
        """v on ``line``: on the lumen the fluid-updated thin velocity when the fluid carries it."""
        if line == LUMEN and self.wall_state.v is not None:
            return self.wall_state.v
        return self.wall.prolongations[line].T @ self.wall_state.V

    def dof_counts(self) -> dict[str, int]:
        out = {}
        if self.wall is not None:
            out["wall"] = int(self.wall.ndofs)
            out["wall_free"] = int(self.stack.free.size)
        if self.fluid_state is not None:
            out["fluid"] = int(self.fluid.channel.ndofs)
        return out

    # -- probes ---------------------------------------------------------------
    def probe_rows(self, probes: tuple[Probe, ...]) -> dict[str, Any]:
        """Each probe's evaluator, built once: a sparse row (wall) or a sampler (fluid)."""
        rows = {}
        for p in probes:
            if p.quantity in ("eta", "v"):
                rows[p.name] = (p.quantity, p.line, self.wall.lines[p.line].basis.probes(np.array([[p.z]])).tocsr())
            elif p.quantity in ("d_z", "d_r"):
                comp = {"d_z": 0, "d_r": 1}[p.quantity]
                rows[p.name] = ("d", None, self.wall.basis.probes(np.array([[p.z], [p.r]])).tocsr()[comp])
            else:
                rows[p.name] = ("fluid", None, self.fluid.probe(p.quantity, p.z, p.r))
        return rows

    def probe_values(self, rows: dict[str, Any]) -> dict[str, float]:
        """The probes' values in the current state (line vectors computed once per line)."""
        lines: dict[tuple[str, int], np.ndarray] = {}
        out = {}
        for name, (kind, line, ev) in rows.items():
            if kind == "fluid":
                out[name] = ev(self.fluid_state, self.fluid_eta)
                continue
            if kind == "d":
                vec = self.wall_state.d
            else:
                if (kind, line) not in lines:
                    lines[kind, line] = self.wall_velocity(line) if kind == "v" else self.eta(line)
                vec = lines[kind, line]
            out[name] = float((ev @ vec)[0])
        return out

    # -- snapshots ------------------------------------------------------------
    def wall_snapshot(self) -> tuple[np.ndarray, dict, dict]:
        """Points, cells and point data of the wall at its reference position.

        ``displacement`` is a 3-vector field, so ParaView's *Warp By Vector*
        shows the deformed wall.
        """
        wall, st = self.wall, self.wall_state
        if wall.basis is None:
            line = wall.lines[0]
            mesh = line.basis.mesh
            vert = line.basis.nodal_dofs[0]
            eta = st.d[vert]
            pts = np.column_stack([mesh.p[0], np.full(mesh.p.shape[1], line.radius), np.zeros(mesh.p.shape[1])])
            disp = np.column_stack([np.zeros_like(eta), eta, np.zeros_like(eta)])
            return pts, {"line": mesh.t.T}, {"displacement": disp, "eta": eta,
                                             "velocity_r": self.wall_velocity(0)[vert]}
        mesh = wall.basis.mesh
        nd = wall.basis.nodal_dofs
        pts = np.column_stack([mesh.p[0], mesh.p[1], np.zeros(mesh.p.shape[1])])
        disp = np.column_stack([st.d[nd[0]], st.d[nd[1]], np.zeros(mesh.p.shape[1])])
        vel = np.column_stack([st.V[nd[0]], st.V[nd[1]], np.zeros(mesh.p.shape[1])])
        return pts, {"triangle": mesh.t.T}, {"displacement": disp, "velocity": vel}

    def fluid_snapshot(self) -> tuple[np.ndarray, dict, dict]:
        """The channel in its physical (deformed) place: velocity, pressure, ALE displacement."""
        pts, tri, data = self.fluid.snapshot(self.fluid_state, self.fluid_eta)
        return _xyz(pts), {"triangle": tri}, {k: _xyz(v) if np.ndim(v) == 2 else v for k, v in data.items()}


def _xyz(a: np.ndarray) -> np.ndarray:
    """(n, 2) in (z, r) → (n, 3) for VTK."""
    return np.column_stack([a, np.zeros(len(a))])
