"""The setup of a run: the case's models built and discretized, frozen for the run.

The setup holds what every step shares and nothing that changes from step
to step: the layer objects, the wall's spaces and assembled stack, the
fluid and its discretization, the coupler.  It also reads a
:class:`~multilayer.scene.state.State`: probes and field snapshots, so couplers
only advance states.  (Solver statistics and phase timings accumulate on
it; they are counters, not state.)
"""

from __future__ import annotations

import time
from typing import Any

import attrs
import numpy as np

from multilayer.case.model import Case, Probe
from multilayer.fluid.contract import ENDS, Fluid, FluidSetup, gives_wall_shear
from multilayer.geometry.contract import Geometry
from multilayer.numerics.linsolve import SolverStats
from multilayer.plugin.registry import Registry
from multilayer.scene.state import State, WallState
from multilayer.wall.checks import LayerError, abstract_problem, raised, type_problem
from multilayer.wall.equilibrium import static_deflection
from multilayer.wall.layer import Layer
from multilayer.wall.prestress import prestress
from multilayer.wall.stack import LUMEN, Stack, WallSpace, fluid_pinned_lines


def build_model(registry: Registry, kind: str, spec) -> Any:
    """The model of ``spec`` (a fluid, a coupler), built with its parameters (a plugin one names built too)."""
    record = registry.get(kind, spec.model).record
    return record.factory(**registry.arguments(record, spec.params))


def build_geometry(registry: Registry, spec) -> Geometry:
    """The geometry of the case's ``[geometry]`` (its model, built with its parameters)."""
    geometry = registry.get("geometry", spec.model).record.factory(**dict(spec.params))
    if not isinstance(geometry, Geometry):
        raise ValueError(f"geometry model {spec.model!r}: the plugin's factory returned {type(geometry).__name__}, "
                         f"not a Geometry")
    return geometry


def build_layer(registry: Registry, spec) -> Layer:
    """The layer of ``spec``, checked to be a layer of the kind its plugin declares.

    Raises
    ------
    LayerError
        Naming the layer when its factory fails or returns something else.
    """
    where = f"{spec.path} ({spec.model})"
    record = registry.get("layer", spec.model).record
    problem = abstract_problem(record.factory)
    if problem:
        raise LayerError(where, [problem])
    try:
        layer = record.factory(**dict(spec.params))
    except Exception as exc:  # the plugin's own code
        raise LayerError(where, [f"the factory raised {raised(exc)}"]) from exc
    problem = type_problem(layer, record.thin)
    if problem:
        raise LayerError(where, [problem])
    return layer


def prestressed(case: Case, stack: Stack, solvers: dict[str, SolverStats]) -> Stack:
    """The ``stack`` built on the mesh with its finite-strain layers on the stress-free reference that holds it
    under ``initial.pressure`` (:mod:`multilayer.wall.prestress`): the one validation found
    (:attr:`Case.reference`, its static solves' counters as ``solvers["static"]``), else found here (counted
    there).  So it is found once a run: on the reference found, the stack is the one its finding ended on, bit
    for bit."""
    found = case.reference
    if found is not None and found.serves(case) and found.displacement.shape == (stack.space.ndofs,):
        solvers["static"] = attrs.evolve(found.stats, backends={})  # the counts, the case's own kept as they are
        return stack.on_reference(found.displacement)
    stats = solvers.setdefault("static", SolverStats())
    return prestress(stack, case.initial.pressure, case.loads.external.value(0.0), stats).stack


@attrs.frozen(eq=False)
class Setup:
    case: Case
    registry: Registry
    geometry: Geometry
    layers: list[Layer]
    fluid: Fluid | None = None
    wall: WallSpace | None = None
    stack: Stack | None = None
    #: factorizations and solves of the systems the coupler builds, by name (``wall``, ``monolithic``, ...)
    solvers: dict[str, SolverStats] = attrs.field(factory=dict)
    timings: dict[str, float] = attrs.field(factory=lambda: {"assembly": 0.0, "output": 0.0})

    @classmethod
    def build(cls, case: Case, registry: Registry, wall_mode: str = "coupled",
              radial_lines: tuple[int, ...] = (), interface_block: bool = False) -> Setup:
        """Build the models, the wall and the fluid's discretization for ``wall_mode``.

        ``wall_mode`` is how the fluid sees the wall: ``coupled``, ``rigid`` or
        ``prescribed`` (what the case's coupler asks, :meth:`Coupler.fluid_wall`);
        ``radial_lines`` the interface lines whose d_z it holds at zero
        (:meth:`Coupler.radial_lines`); ``interface_block`` whether its interface terms fill the line × line
        block of the fluid's matrix (:meth:`Coupler.fluid_interface_block`).  A fluid on a thick first layer pins
        the lumen line's ends in both components (the domain keeps its length).
        """
        t0 = time.perf_counter()
        geometry = build_geometry(registry, case.geometry)
        layers = [build_layer(registry, spec) for spec in case.layers]
        fluid = build_model(registry, "fluid", case.fluid) if case.fluid is not None else None
        g, m = case.geometry, case.mesh
        wall = stack = None
        solvers: dict[str, SolverStats] = {}
        if layers:
            wall = WallSpace.build(layers, geometry, g.length, g.radius, m.nz, m.order,
                                   [spec.cells for spec in case.layers], [spec.model for spec in case.layers])
            stack = Stack.assemble(wall, radial_lines, fluid_pinned_lines(layers, fluid is not None))
            if case.initial.prestress:  # the mesh is the wall imaged at P⁰: its layers on the reference that holds it
                stack = prestressed(case, stack, solvers)
        if fluid is not None:
            line = wall.lines[LUMEN] if wall is not None else None
            # the lumen's DOFs the wall holds at rest (a band whose inner face slides): the fluid's u_r is 0 there
            held = (np.flatnonzero(np.isin(wall.line_dofs(LUMEN), stack.fixed)) if stack is not None
                    else np.zeros(0, dtype=np.int64))
            fluid.setup(FluidSetup(geometry, g.length, g.radius, m.nz, m.nr, m.order, m.grading, wall_mode,
                                   case.solver, case.reuse, line, {end: getattr(case.loads, end) for end in ENDS},
                                   interface_block, held,
                                   smallest_step=case.time.smallest if case.time.adaptive else None))
        setup = cls(case=case, registry=registry, geometry=geometry, layers=layers, fluid=fluid, wall=wall,
                    stack=stack, solvers=solvers)
        setup.timings["assembly"] += time.perf_counter() - t0
        return setup

    def initial_state(self) -> State:
        """t = 0: the case's initial wall (essential DOFs zeroed), the fluid at rest on the wall's domain.

        With ``[initial] pressure`` the wall is the static deflection under it (and the external pressure at
        t = 0): :func:`~multilayer.wall.equilibrium.static_deflection`; with ``prestress`` too, the mesh itself
        (d = 0), which its layers' reference holds under it (:mod:`multilayer.wall.prestress`).
        """
        wall = v = eta = fluid = None
        if self.wall is not None:
            init = self.case.initial
            if init.pressure is None:
                d0 = self.wall.interpolate(init.displacement_z, init.displacement_r)
            elif init.prestress:
                d0 = np.zeros(self.wall.ndofs)
            else:
                d0 = static_deflection(self.stack, init.pressure, self.case.loads.external.value(0.0),
                                       None if self.stack.linear else self.stats("static"))
            v0 = self.wall.interpolate(init.velocity_z, init.velocity_r)
            wall = WallState(self.stack.zero_fixed(d0), self.stack.zero_fixed(v0))
        if self.fluid is not None:
            pressure = self.case.initial.pressure
            fluid = self.fluid.initial_state() if pressure is None else self.fluid.initial_state(pressure=pressure)
            if wall is not None:
                R = self.wall.restrictions[LUMEN]
                eta, v = R @ wall.d, R @ wall.V
            else:
                eta = np.zeros(self.fluid.line.ndofs)
        return State(0, 0.0, wall, fluid, v, eta)

    def stats(self, name: str) -> SolverStats:
        """The counters of the coupler's system ``name`` (created on first use)."""
        return self.solvers.setdefault(name, SolverStats())

    @property
    def dt(self) -> float:
        return self.case.time.dt

    @property
    def steps(self) -> int:
        return self.case.time.steps

    def windows(self, start: int = 0):
        """(n, tⁿ, tⁿ⁺¹) for every step of the run from step ``start``."""
        dt = self.dt
        for n in range(start, self.steps):
            yield n, n * dt, (n + 1) * dt

    # -- wall quantities ----------------------------------------------------
    def eta(self, state: State, line: int = LUMEN) -> np.ndarray:
        """η on ``line`` in the line's own numbering."""
        return self.wall.restrictions[line] @ state.wall.d

    def wall_velocity(self, state: State, line: int = LUMEN) -> np.ndarray:
        """v on ``line``: on the lumen the fluid-updated thin velocity when the fluid carries it."""
        if line == LUMEN and state.v is not None:
            return state.v
        return self.wall.restrictions[line] @ state.wall.V

    def dof_counts(self) -> dict[str, int]:
        out = {}
        if self.wall is not None:
            out["wall"] = int(self.wall.ndofs)
            out["wall_free"] = int(self.stack.free.size)
        if self.fluid is not None:
            out["fluid"] = int(self.fluid.ndofs)
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

    def probe_values(self, rows: dict[str, Any], state: State) -> dict[str, float]:
        """The probes' values in ``state`` (line vectors computed once per line)."""
        lines: dict[tuple[str, int], np.ndarray] = {}
        out = {}
        for name, (kind, line, ev) in rows.items():
            if kind == "fluid":
                eta_z = state.extra.get("eta_z")  # an axially moving domain's (no-slip at a thick band)
                out[name] = ev(state.fluid, state.eta) if eta_z is None else ev(state.fluid, state.eta, eta_z)
                continue
            if kind == "d":
                vec = state.wall.d
            else:
                if (kind, line) not in lines:
                    lines[kind, line] = self.wall_velocity(state, line) if kind == "v" else self.eta(state, line)
                vec = lines[kind, line]
            out[name] = float((ev @ vec)[0])
        return out

    # -- the wall shear stress ---------------------------------------------------
    @property
    def gives_wall_shear(self) -> bool:
        """Whether the run has a fluid that gives its wall shear stress (``wss_lumen.csv``, ``lumen`` snapshots)."""
        return self.fluid is not None and gives_wall_shear(self.fluid)

    def wall_shear(self, state: State) -> np.ndarray:
        """τ_w on the lumen (dyn/cm²), a line vector of the fluid's line (:meth:`Fluid.wall_shear`)."""
        return self.fluid.wall_shear(state.fluid, state.eta, state.extra.get("eta_z"))

    # -- snapshots ------------------------------------------------------------
    def lumen_snapshot(self, state: State) -> tuple[np.ndarray, dict, dict]:
        """The lumen Γ in its physical place, a line of the fluid's line vertices, with ``wss`` (τ_w, dyn/cm²).

        In ParaView the line lies on the fluid snapshot's wall: *Plot Data* draws τ_w along it.
        """
        line = self.fluid.line
        mesh, vertices = line.basis.mesh, line.basis.nodal_dofs[0]
        eta = np.zeros(line.ndofs) if state.eta is None else state.eta
        eta_z = state.extra.get("eta_z")
        z = mesh.p[0] + (0.0 if eta_z is None else eta_z[vertices])
        pts = np.column_stack([z, line.radius + eta[vertices], np.zeros(len(vertices))])
        return pts, {"line": mesh.t.T}, self._measured(pts, {"wss": self.wall_shear(state)[vertices]})

    def wall_snapshot(self, state: State) -> tuple[np.ndarray, dict, dict]:
        """Points, cells and point data of the wall at its reference position.

        Every wall, a line or bands, writes the same fields at the mesh
        vertices (a P2 field's vertex values): ``displacement`` and
        ``velocity``, 3-vectors (ParaView's *Warp By Vector* on
        ``displacement`` shows the deformed wall).  A thin-only wall's
        velocity is the thin layer's own (the fluid's trace when it carries it).
        """
        wall, st = self.wall, state.wall
        if wall.basis is None:
            line = wall.lines[0]
            mesh = line.basis.mesh
            vert = line.basis.nodal_dofs[0]
            zero = np.zeros(len(vert))
            pts = np.column_stack([mesh.p[0], np.full(mesh.p.shape[1], line.radius), np.zeros(mesh.p.shape[1])])
            disp = np.column_stack([zero, st.d[vert], zero])
            vel = np.column_stack([zero, self.wall_velocity(state, 0)[vert], zero])
            return pts, {"line": mesh.t.T}, self._measured(pts, {"displacement": disp, "velocity": vel})
        mesh = wall.basis.mesh
        nd = wall.basis.nodal_dofs
        pts = np.column_stack([mesh.p[0], mesh.p[1], np.zeros(mesh.p.shape[1])])
        disp = np.column_stack([st.d[nd[0]], st.d[nd[1]], np.zeros(mesh.p.shape[1])])
        vel = np.column_stack([st.V[nd[0]], st.V[nd[1]], np.zeros(mesh.p.shape[1])])
        return pts, {"triangle": mesh.t.T}, self._measured(pts, {"displacement": disp, "velocity": vel})

    def fluid_snapshot(self, state: State) -> tuple[np.ndarray, dict, dict]:
        """The channel in its physical (deformed) place: velocity and pressure at the vertices.

        The points are already where the fluid is, so no displacement field is
        written (Warp By Vector would move the channel twice).
        """
        pts, tri, data = self.fluid.snapshot(state.fluid, state.eta, state.extra.get("eta_z"))
        return _xyz(pts), {"triangle": tri}, self._measured(pts, {k: _xyz(v) if np.ndim(v) == 2 else v
                                                                 for k, v in data.items() if k != "displacement"})

    def _measured(self, points: np.ndarray, data: dict) -> dict:
        """``data`` with the point field ``measure`` = weight(r) at the points, in a geometry whose measure
        varies with r (a tube's 2πr): ParaView's *Integrate Variables* of ``measure`` × f over the meridian is
        ∫ f dV of the geometry (docs/case-files.md, "Results").  A planar snapshot is left as it is."""
        if self.geometry.radial_power:
            data["measure"] = np.asarray(self.geometry.weight(points[:, 1]), dtype=float)
        return data


def _xyz(a: np.ndarray) -> np.ndarray:
    """(n, 2) in (z, r) → (n, 3) for VTK."""
    return np.column_stack([a, np.zeros(len(a))])
