"""The incompressible fluid of the channel: one class, advection on or off.

``navier-stokes`` and ``stokes`` are the same model of theory §6 A2; Stokes
drops the two advection terms and keeps everything else, the moving-domain
term included.  The model holds its physical parameters; :meth:`setup`
attaches a discretization (a :class:`multilayer_plugins.channel.step.FluidStep`) on
which the other methods act.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from multilayer.fluid.contract import Fluid, FluidSetup
from multilayer.geometry.spaces import LineSpace
from multilayer.numerics.linsolve import SolverStats
from multilayer.plugin.records import Param
from multilayer_plugins.channel import probes
from multilayer_plugins.channel.ale import ALEFields, deformation, volume_element
from multilayer_plugins.channel.channel import Channel
from multilayer_plugins.channel.end_convection import END_PRESSURES
from multilayer_plugins.channel.ledger import fluid_kinetic
from multilayer_plugins.channel.stabilization import GRAD_DIV, KINDS, Stabilization
from multilayer_plugins.channel.step import FluidState, FluidStep, FluidSystem, Solution
from multilayer_plugins.channel.wall_shear import WallShear

#: The parameters of every channel fluid, for its plugin record.
PARAMS = (
    Param("density", "ρ_f", "g/cm³", gt=0.0, doc="density of the fluid"),
    Param("viscosity", "μ", "P = g/(cm·s)", gt=0.0, doc="dynamic viscosity of the fluid"),
)

#: The parameters of the Navier–Stokes fluid: PARAMS, what its open ends' pressures mean (theory §10) and its
#: stabilization of convection (theory §5, "Stabilization").
NAVIER_STOKES_PARAMS = PARAMS + (
    Param("ends", "", "", "static-pressure", type=str, choices=END_PRESSURES,
          doc="what the open ends' pressure data prescribe: p, with a backflow term where the flow enters, "
              "or p + ρ_f|u|²/2 (the seed's)"),
    Param("backflow", "β", "1", None, ge=0.0,
          doc="strength of the backflow term of static-pressure ends (default 1: no kinetic energy enters)"),
    Param("stabilization", "", "", default="supg", type=str, choices=KINDS,
          doc="residual-based stabilization of convection: 'supg' (SUPG on the momentum residual, grad-div if grad_div > 0) "
              "or 'none' (Galerkin)"),
    Param("grad_div", "γ", "1", default=GRAD_DIV, ge=0.0,
          doc="scale γ of grad-div's cell viscosity τ_C = γ|a|h/2 under 'supg' (0: SUPG alone)"),
    Param("supg_dt", "Δt_τ", "s", None, gt=0.0,
          doc="the time step whose τ_M SUPG uses wherever the step is longer (default: each step its own); "
              "set it at or below an adaptive run's steps so that every step solves one stabilized problem"),
)


class ChannelFluid(Fluid):
    """An incompressible Newtonian fluid in the 2D channel, on the ALE reference domain.

    Parameters
    ----------
    density : float
        ρ_f (g/cm³), > 0.
    viscosity : float
        μ (poise, g/(cm·s)), > 0.

    Examples
    --------
    >>> from multilayer.fluid.contract import Domain, FluidSetup
    >>> from multilayer.functions.loads import ConstantPressure
    >>> from multilayer.numerics.timescheme import named
    >>> from multilayer_plugins.planar import Planar
    >>> from multilayer_plugins.pressure import PressureEnd
    >>> fluid = NavierStokes(density=1.0, viscosity=0.035)
    >>> ends = {"inlet": PressureEnd(ConstantPressure(10.0))}
    >>> step = fluid.setup(FluidSetup(Planar(), 1.0, 0.5, nz=2, nr=2, order=2, wall="rigid", ends=ends))
    >>> state = fluid.initial_state()
    >>> still = Domain.still(fluid.line.ndofs)
    >>> sol, terms = fluid.step([state], still, named("backward-euler"), 1e-3, (0.0, 1e-3))
    >>> sol.state.u.shape == (step.channel.nu,), abs(terms["a2.residual"]) < 1e-12 * terms["a2.scale"]
    (True, True)
    """

    #: whether the advection terms are assembled
    advection: ClassVar[bool] = True

    def __init__(self, density: float, viscosity: float):
        for name, value in (("density", density), ("viscosity", viscosity)):
            if not value > 0.0:
                raise ValueError(f"fluid {name} must be > 0, got {value!r}")
        self.density = float(density)
        self.viscosity = float(viscosity)
        #: the backflow term's β of static-pressure ends; None: total-pressure ends (theory §10)
        self.backflow: float | None = None
        self._discrete: FluidStep | None = None
        self._shear: WallShear | None = None  # built at the first wall_shear of a discretization

    def __repr__(self) -> str:
        return f"{type(self).__name__}(density={self.density!r}, viscosity={self.viscosity!r})"

    def setup(self, spec: FluidSetup) -> FluidStep:
        """Discretize for ``spec``: the channel L × R (cm) in nz × nr cells, element ``order``, in its geometry.

        ``spec.wall`` is ``"coupled"``, ``"rigid"`` or ``"prescribed"`` (see
        :mod:`multilayer_plugins.channel.step`); ``spec.ends`` the conditions of
        the open ends.  Returns the discretization, which is also kept on the
        fluid for the methods below.
        """
        channel = Channel.build(spec.geometry, spec.length, spec.radius, spec.nz, spec.nr, spec.order, spec.grading,
                                spec.line)
        self._discrete = FluidStep(channel, self.density, self.viscosity, self.advection, spec.wall, spec.solver,
                                   spec.reuse, spec.ends, self.backflow, spec.interface_block, spec.held,
                                   self.stabilization(channel, spec.smallest_step))
        self._shear = None
        return self._discrete

    def stabilization(self, channel: Channel, smallest_step: float | None = None) -> Stabilization | None:
        """The residual-based stabilization of the step on ``channel`` (an adaptive run's steps no shorter than
        ``smallest_step``): none for the Galerkin fluid."""
        return None

    @property
    def discrete(self) -> FluidStep:
        if self._discrete is None:
            raise RuntimeError("call fluid.setup(...) before using the discretization")
        return self._discrete

    @property
    def channel(self) -> Channel:
        return self.discrete.channel

    @property
    def line(self) -> LineSpace:
        """The interface line r = R; the fluid's wall u_r DOFs are its DOFs."""
        return self.channel.line

    @property
    def ndofs(self) -> int:
        return self.discrete.ndofs

    @property
    def interface_dofs(self) -> np.ndarray:
        return self.discrete.interface_dofs

    @property
    def interface_z_dofs(self) -> np.ndarray:
        return self.discrete.interface_z_dofs

    @property
    def stats(self) -> SolverStats:
        return self.discrete.stats

    @property
    def timings(self) -> dict[str, float]:
        return {"assembly": self.discrete.assembly_s, "ledger": self.discrete.ledger_s}

    def initial_state(
        self, velocity: Callable[[np.ndarray, np.ndarray], tuple] | None = None, eta: np.ndarray | None = None,
        pressure: float = 0.0,
    ) -> FluidState:
        """Rest, or the interpolant of ``velocity(z, r) -> (u_z, u_r)`` given in the physical domain of ``eta``;
        the pressure uniform at ``pressure``."""
        ch = self.channel
        eta = self._eta(eta)
        u = np.zeros(ch.nu)
        if velocity is not None:
            R = ch.radius

            def on_reference(zh, rh):
                return velocity(zh, rh * (R + probes.wall_displacement(ch, eta, zh)) / R)

            u = ch.interpolate(on_reference)
        p = np.full(ch.pressure.N, float(pressure))
        return FluidState(u, p, ch.wall_trace(u), self.discrete.ends.initial_state())

    def state_to_data(self, state: FluidState) -> dict[str, Any]:
        """u, p, v and each end's state as its condition writes it (a checkpoint's data)."""
        conditions = self.discrete.ends.conditions
        return {"u": state.u, "p": state.p, "v": state.v,
                "ends": {end: conditions[end].state_to_data(s) for end, s in state.ends.items()}}

    def state_from_data(self, data: Any) -> FluidState:
        """The :class:`FluidState` of ``data`` (:meth:`state_to_data`'s), each array's dtype and shape checked
        against this discretization and each end's state by its condition (ValueError otherwise)."""
        ch, conditions = self.channel, self.discrete.ends.conditions
        if not isinstance(data, dict) or set(data) != {"u", "p", "v", "ends"}:
            raise ValueError("the fluid's state should have the fields u, p, v, ends")
        for name, n in (("u", ch.nu), ("p", ch.pressure.N), ("v", self.line.ndofs)):
            a = data[name]
            if not (isinstance(a, np.ndarray) and a.dtype == np.float64 and a.shape == (n,)):
                raise ValueError(f"the fluid's {name} should be a float64 array of shape ({n},), not "
                                 f"{getattr(a, 'dtype', type(a).__name__)} {getattr(a, 'shape', '')}")
        ends = data["ends"]
        if not isinstance(ends, dict) or set(ends) != set(conditions):
            raise ValueError(f"the fluid's state should have the states of the ends {', '.join(conditions)}")
        return FluidState(data["u"], data["p"], data["v"],
                          {end: conditions[end].state_from_data(ends[end]) for end in conditions})

    def system(self, history, domain, scheme, dt, times, interface=None) -> FluidSystem:
        """See :meth:`multilayer_plugins.channel.step.FluidStep.system`."""
        return self.discrete.system(history, domain, scheme, dt, times, interface)

    def matrix(self, system: FluidSystem):
        """(A, b, fixed DOFs, fixed values) of ``system``, A in CSR with the interface terms."""
        return self.discrete.pattern.matrix(system.data), system.rhs, system.fixed, system.fixed_values

    def solve(self, system: FluidSystem) -> Solution:
        return self.discrete.solve(system)

    def prescribe(self, system: FluidSystem, wall_velocity: np.ndarray,
                  wall_velocity_z: np.ndarray | None = None) -> FluidSystem:
        return self.discrete.prescribe(system, wall_velocity, wall_velocity_z)

    def advance(self, system: FluidSystem, mean: np.ndarray) -> Solution:
        return self.discrete.advance(system, mean)

    def identity(self, system, solution, eta_old, eta_new, axial=None) -> dict[str, float]:
        return self.discrete.identity(system, solution, eta_old, eta_new, axial)

    def reaction(self, system: FluidSystem, mean: np.ndarray, axial: bool = False) -> np.ndarray:
        return self.discrete.reaction(system, mean, axial)

    def wall_velocity(self, state: FluidState) -> np.ndarray:
        return state.v

    def energy(self, state: FluidState, eta: np.ndarray | None = None,
               eta_z: np.ndarray | None = None) -> dict[str, float]:
        """``kinetic.fluid`` and what the ends' conditions store (a Windkessel's capacitor), by ledger column."""
        return {"kinetic.fluid": self.kinetic_energy(state, eta, eta_z), **self.discrete.ends.energy(state.ends)}

    def kinetic_energy(self, state: FluidState, eta: np.ndarray | None = None,
                       eta_z: np.ndarray | None = None) -> float:
        """½ρ_f ∫ J|u|² on the domain of ``eta`` (moved axially by ``eta_z`` when given)."""
        ch = self.channel
        eta = self._eta(eta)
        if eta_z is not None:
            J = volume_element(ch, deformation(ch, eta, self.discrete.extension.at_quad(eta_z)))
            return fluid_kinetic(ch, self.density, J, state.u)
        fields = ALEFields.at(ch, eta, np.zeros_like(eta))
        return fluid_kinetic(ch, self.density, fields.J, state.u)

    def flow_rate(self, state: FluidState, eta: np.ndarray | None, z: float, eta_z: np.ndarray | None = None) -> float:
        """Volume flux through the section at z (cm²/s), moved axially by ``eta_z`` when given."""
        return probes.flow_rate(self.channel, state.u, self._eta(eta), z, self._axial(eta_z))

    def probe(self, quantity: str, z: float, rhat: float | None = None):
        """A function (state, η) → value for ``quantity`` (``u_z``, ``u_r``, ``p`` at the
        reference point (z, r̂), or ``flow_rate`` through the section z), built once."""
        ch = self.channel
        if quantity == "flow_rate":
            radial = probes.flow_rate_sampler(ch, z)
            axial = []  # built at the first call with the lumen's d_z (no-slip at a thick band)

            def flow_rate(state, eta, eta_z=None):
                if eta_z is None:
                    return radial(state.u, self._eta(eta))
                if not axial:
                    axial.append(probes.flow_rate_sampler(ch, z, self.discrete.extension))
                return axial[0](state.u, self._eta(eta), eta_z)

            return flow_rate
        point = probes.reference_point_sampler(ch, quantity, z, rhat)
        return lambda state, eta, eta_z=None: point(state.u, state.p)

    def velocity(self, state: FluidState, eta: np.ndarray | None, z, r, eta_z: np.ndarray | None = None) -> np.ndarray:
        """(u_z, u_r) at physical points, a (2, n) array (cm/s); the domain moved axially by ``eta_z`` when given."""
        return probes.velocity(self.channel, state.u, self._eta(eta), z, r, self._axial(eta_z))

    def pressure(self, state: FluidState, eta: np.ndarray | None, z, r, eta_z: np.ndarray | None = None) -> np.ndarray:
        """Pressure at physical points (dyn/cm²); the domain moved axially by ``eta_z`` when given."""
        return probes.pressure(self.channel, state.p, self._eta(eta), z, r, self._axial(eta_z))

    def wall_shear(self, state: FluidState, eta: np.ndarray | None = None,
                   eta_z: np.ndarray | None = None) -> np.ndarray:
        """τ_w = −t·2μD(u)n on the lumen at the line's DOFs (dyn/cm²), the domain moved axially by ``eta_z`` when
        given; see :mod:`multilayer_plugins.channel.wall_shear`."""
        if self._shear is None:
            self._shear = WallShear(self.channel, self.viscosity)
        return self._shear(state.u, self._eta(eta), self._axial(eta_z))

    def snapshot(self, state: FluidState, eta: np.ndarray | None = None, eta_z: np.ndarray | None = None):
        """(points, triangles, point_data) in the deformed geometry, moved axially by the harmonic extension of
        ``eta_z`` when given; see :func:`probes.snapshot`."""
        axial = None if eta_z is None else self.discrete.extension.at_vertices(eta_z)
        return probes.snapshot(self.channel, state.u, state.p, self._eta(eta), axial)

    def _eta(self, eta: np.ndarray | None) -> np.ndarray:
        return np.zeros(self.line.ndofs) if eta is None else eta

    def _axial(self, eta_z: np.ndarray | None):
        """(the extension, d_z) of an axially moved domain, None for the radial map."""
        return None if eta_z is None else (self.discrete.extension, eta_z)


class NavierStokes(ChannelFluid):
    """Incompressible Navier–Stokes (ALE, skew-symmetric advection), SUPG- and grad-div-stabilized by default.

    Parameters
    ----------
    density, viscosity : float
        As :class:`ChannelFluid`.
    ends : str
        What the open ends' pressure data prescribe (theory §10, "Open ends under backflow"):
        ``"static-pressure"`` p, with the backflow term of strength ``backflow`` = β (default 1) where the
        flow enters (:mod:`multilayer_plugins.channel.end_convection`), or ``"total-pressure"``
        p + ½ρ_f|u|² (the skew advection's natural condition, the seed's).
    backflow : float, optional
        β ≥ 0 of static-pressure ends.
    stabilization : str
        ``"supg"`` (default) or ``"none"`` (:mod:`multilayer_plugins.channel.stabilization`).
    grad_div : float
        γ ≥ 0, the scale of grad-div's τ_C under ``"supg"`` (default :data:`GRAD_DIV`; 0: SUPG alone).
    supg_dt : float, optional
        Δt_τ > 0 (s): τ_M's time term is that of a step Δt_τ wherever the step is longer (default: each step's own;
        :class:`~multilayer_plugins.channel.stabilization.Stabilization`).
    """

    advection = True

    def __init__(self, density: float, viscosity: float, ends: str = "static-pressure",
                 backflow: float | None = None, stabilization: str = "supg", grad_div: float = GRAD_DIV,
                 supg_dt: float | None = None):
        super().__init__(density, viscosity)
        if ends not in END_PRESSURES:
            raise ValueError(f"fluid.ends must be one of {END_PRESSURES}, got {ends!r}")
        if ends == "total-pressure" and backflow is not None:
            raise ValueError(f"fluid.backflow = {backflow!r} is the backflow term of static-pressure ends: "
                             f"set fluid.ends = \"static-pressure\" (total-pressure ends let no kinetic energy in)")
        if backflow is not None and not backflow >= 0.0:
            raise ValueError(f"fluid.backflow must be ≥ 0, got {backflow!r}")
        if stabilization not in KINDS:
            raise ValueError(f"fluid stabilization must be one of {', '.join(KINDS)}, got {stabilization!r}")
        if not grad_div >= 0.0:
            raise ValueError(f"fluid grad_div must be ≥ 0, got {grad_div!r}")
        if supg_dt is not None and not supg_dt > 0.0:
            raise ValueError(f"fluid supg_dt must be > 0 s, got {supg_dt!r}")
        self.end_pressure = ends
        self.backflow = (1.0 if backflow is None else float(backflow)) if ends == "static-pressure" else None
        self.kind = stabilization
        self.grad_div = float(grad_div)
        self.supg_dt = None if supg_dt is None else float(supg_dt)

    def __repr__(self) -> str:
        ends = "" if self.backflow is None else f", ends={self.end_pressure!r}, backflow={self.backflow!r}"
        return (f"{type(self).__name__}(density={self.density!r}, viscosity={self.viscosity!r}{ends}, "
                f"stabilization={self.kind!r}, grad_div={self.grad_div!r}"
                + ("" if self.supg_dt is None else f", supg_dt={self.supg_dt!r}") + ")")

    def stabilization(self, channel: Channel, smallest_step: float | None = None) -> Stabilization | None:
        """SUPG and grad-div; τ_M that of a step ``supg_dt`` on every longer step, by default (adaptive steps) that
        of the smallest step the run may take, so that the stabilized problem does not change with the step."""
        if self.kind == "none":
            return None
        supg_dt = self.supg_dt if self.supg_dt is not None else smallest_step
        return Stabilization(channel, self.density, self.viscosity, self.grad_div, supg_dt)


class Stokes(ChannelFluid):
    """Unsteady Stokes: Navier–Stokes without the advection terms."""

    advection = False


def wall_motion(line: LineSpace, eta: Callable[[float, np.ndarray], np.ndarray], t: float, dt: float):
    """(ηⁿ, η^{n+1}, c) on the line for a prescribed law ``eta(t, z)`` (cm): c = (η^{n+1} − ηⁿ)/Δt.

    With c the wall's u_r over the step, ηⁿ + Δt c = η^{n+1} holds exactly
    (the discrete mass balance of the moving channel).
    """
    now = np.asarray(eta(t, line.z), dtype=float)
    then = np.asarray(eta(t + dt, line.z), dtype=float)
    return now, then, (then - now) / dt
