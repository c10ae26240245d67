"""The fluid contract: what a coupler asks of a fluid, and the domain and interface terms it passes."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import attrs
import numpy as np
import scipy.sparse as sp

from multilayer.boundary.contract import BoundaryCondition
from multilayer.geometry.contract import Geometry
from multilayer.geometry.spaces import LineSpace
from multilayer.numerics.linsolve import Reuse

if TYPE_CHECKING:  # pragma: no cover
    from multilayer.numerics.linsolve import SolverStats
    from multilayer.numerics.timescheme import TimeScheme


#: the fluid's open ends: z = 0 and z = L
ENDS = ("inlet", "outlet")
#: the wall modes (:attr:`FluidSetup.wall`) in which the fluid is given the wall's motion and moves no wall
#: itself: the lumen's volume is then data, and a flow rate at both ends has no solution
GIVEN_WALLS = ("rigid", "prescribed")


@attrs.frozen(eq=False)
class FluidSetup:
    """What a fluid is discretized for: the geometry, the channel and its mesh, the wall mode, the ends.

    ``wall`` is how the fluid sees the wall: ``coupled`` (its u_r on the wall
    is an unknown the coupler ties to the wall), ``no-slip`` (its u_r and u_z
    there are, for a fluid on a thick band), ``rigid`` (u = 0, the domain
    never moves) or ``prescribed`` (u_r given on the wall).  ``ends`` holds
    the condition of each open end (``inlet``, ``outlet``); an end left out
    is traction-free.  ``line`` is the interface line's space when the caller
    already has it (the wall's lumen line); ``reuse`` when a changing matrix
    is refactorized; ``interface_block`` when the coupler's interface
    matrix fills the whole line × line block (a wall's step condensed on Γ).
    ``smallest_step`` is the shortest step an adaptive run may take
    (``time.dt_min``; None with fixed steps): a fluid whose discrete problem
    depends on the step (a stabilization's parameter) holds it fixed on
    every longer step, so that the error estimate sees all that changes
    with the step.
    """

    geometry: Geometry
    length: float  #: L (cm)
    radius: float  #: R (cm)
    nz: int
    nr: int
    order: int = 2
    grading: float = 1.0
    wall: str = "coupled"
    solver: str = "superlu"
    reuse: Reuse = Reuse()
    line: LineSpace | None = None
    ends: Mapping[str, BoundaryCondition] = attrs.field(factory=dict)
    interface_block: bool = False
    #: the interface line's DOFs the wall holds at rest (its essential DOFs on the lumen): u_r = 0 there
    held: np.ndarray = attrs.field(factory=lambda: np.zeros(0, dtype=np.int64), eq=False)
    smallest_step: float | None = None  #: adaptive steps: the shortest step (s); None with fixed steps

    def __attrs_post_init__(self):
        unknown = set(self.ends) - set(ENDS)
        if unknown:
            raise ValueError(f"the fluid's ends are {', '.join(ENDS)}; not {', '.join(sorted(unknown))}")


@attrs.frozen(eq=False)
class Domain:
    """The fluid domain of one step, explicit in time: line vectors on the interface line.

    ``eta`` is the wall displacement of the geometry the step is assembled
    on (J_m, ∇^η); ``velocity`` the wall velocity c that moves the domain
    during the step (∂_t J = c/R, ALE velocity w = c r̂/R).  ``eta_z`` and
    ``velocity_z``, when given, move it axially as well
    (:meth:`multilayer_plugins.channel.ale.ALEFields.moving`).
    """

    eta: np.ndarray
    velocity: np.ndarray
    #: the lumen's axial displacement and velocity under no-slip at a thick first layer (the domain then
    #: moves axially too, by their harmonic extension); None under the radial map
    eta_z: np.ndarray | None = None
    velocity_z: np.ndarray | None = None

    @classmethod
    def still(cls, n: int) -> Domain:
        """The reference channel at rest (n line DOFs)."""
        return cls(np.zeros(n), np.zeros(n))


@attrs.frozen(eq=False)
class Interface:
    """Terms a coupler adds on the fluid's wall u_r rows, in line numbering: R v̄ − r.

    In the kinematically coupled scheme R is the wall step condensed on the
    line (its impedance, a dense block: :attr:`FluidSetup.interface_block`)
    or, in the paper's form, (α₀/β₀) M/Δt with M = ρ₁h∫vψ the thin layer's
    mass; r carries what the wall's step gives without the fluid.
    """

    matrix: sp.spmatrix
    rhs: np.ndarray


class Fluid(ABC):
    """An incompressible fluid in the channel under the wall.

    A fluid is discretized once (:meth:`setup`) for a wall mode, then
    advanced step by step by a coupler through :meth:`system` (the linear
    system of one step on a given domain, for a time scheme), :meth:`solve`
    and :meth:`identity` (the step's energy terms); :meth:`step` does the
    three.  A monolithic coupler takes the system's matrix and right-hand
    side (:meth:`matrix`), adds the wall to them through
    :attr:`interface_dofs`, solves, and hands the solution back with
    :meth:`advance`.  Line vectors (η, v) are in the numbering of
    :attr:`line`, the interface line r = R shared with the wall.
    """

    density: float  #: ρ_f (g/cm³)
    viscosity: float  #: μ (poise)

    @abstractmethod
    def setup(self, spec: FluidSetup) -> Any:
        """Discretize for ``spec`` (geometry, channel, mesh, wall mode, the ends' conditions); returns the
        discretization, which the fluid keeps for the methods below."""

    @property
    @abstractmethod
    def line(self) -> LineSpace:
        """The interface line whose DOFs are the fluid's wall u_r DOFs."""

    @property
    @abstractmethod
    def ndofs(self) -> int:
        """Unknowns of the fluid's system."""

    @property
    @abstractmethod
    def interface_dofs(self) -> np.ndarray:
        """The unknown of the fluid's system that is the wall's u_r at each line DOF."""

    @property
    def interface_z_dofs(self) -> np.ndarray:
        """The unknown of the fluid's system that is the wall's u_z at each line DOF (no-slip at a thick band)."""
        raise NotImplementedError(f"{type(self).__name__} has no wall u_z unknowns: it cannot take lumen = 'no-slip'")

    @property
    @abstractmethod
    def stats(self) -> SolverStats:
        """Factorizations and solves of the fluid's own systems."""

    @property
    @abstractmethod
    def timings(self) -> dict[str, float]:
        """Seconds spent in ``assembly`` and ``ledger`` so far."""

    @abstractmethod
    def initial_state(self) -> Any:
        """The fluid at rest; a fluid that can start at rest at a uniform pressure (``[initial] pressure``)
        takes ``pressure=`` (dyn/cm²) as well, called so only when a case sets it."""

    def state_to_data(self, state: Any) -> dict[str, Any]:
        """``state`` as data a checkpoint can hold: a mapping of arrays, numbers, strings, None, lists,
        tuples and mappings (no objects; :func:`multilayer.runner.checkpoint.encode`).

        A fluid whose states are not written as data cannot be checkpointed (the default refuses).
        """
        raise NotImplementedError(f"{type(self).__name__} gives no state_to_data: its runs cannot be checkpointed")

    def state_from_data(self, data: Any) -> Any:
        """The state :meth:`state_to_data` gave ``data`` for, its types and shapes checked against this
        discretization (ValueError for anything else: a checkpoint is refused then)."""
        raise NotImplementedError(f"{type(self).__name__} gives no state_from_data: its runs cannot be resumed")

    @abstractmethod
    def system(self, history: Sequence[Any], domain: Domain, scheme: TimeScheme, dt: float,
               times: tuple[float, float], interface: Interface | None = None) -> Any:
        """The linear system of one step [tⁿ, tⁿ⁺¹] = ``times`` on ``domain`` (history: the states at tⁿ,
        t^{n−1}, ...), the ends' conditions asked for their tractions over the scheme's window of the step."""

    @abstractmethod
    def matrix(self, system: Any) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray, np.ndarray]:
        """(A, b, fixed DOFs, their values) of ``system``: A x̄ = b on the free DOFs."""

    @abstractmethod
    def solve(self, system: Any) -> Any:
        """Solve ``system``; the result has ``state`` (the new state) and ``mean`` (the test-level x̄)."""

    @abstractmethod
    def prescribe(self, system: Any, wall_velocity: np.ndarray, wall_velocity_z: np.ndarray | None = None) -> Any:
        """``system`` with the wall's u_r prescribed to ``wall_velocity`` (a line vector; prescribed mode), and
        its u_z to ``wall_velocity_z`` under no-slip at a thick band.

        Only the Dirichlet data change: a Dirichlet–Neumann coupler iterates on
        it without refactorizing.
        """

    @abstractmethod
    def advance(self, system: Any, mean: np.ndarray) -> Any:
        """The solution of ``system`` from its test-level unknowns x̄ solved elsewhere."""

    @abstractmethod
    def identity(self, system: Any, solution: Any, eta_old: np.ndarray, eta_new: np.ndarray,
                 axial: tuple[np.ndarray, np.ndarray] | None = None) -> dict[str, float]:
        """The step's energy terms (see :meth:`multilayer_plugins.channel.step.FluidStep.identity`); ``axial``
        the lumen's d_z at tⁿ and tⁿ⁺¹ under an axial mesh motion."""

    @abstractmethod
    def reaction(self, system: Any, mean: np.ndarray, axial: bool = False) -> np.ndarray:
        """The fluid's residual on the wall's u_r rows (its u_z rows if ``axial``) as a line vector: minus its
        force on the wall."""

    def step(self, history: Sequence[Any], domain: Domain, scheme: TimeScheme, dt: float,
             times: tuple[float, float], interface: Interface | None = None, eta_old: np.ndarray | None = None,
             eta_new: np.ndarray | None = None) -> tuple[Any, dict[str, float]]:
        """One step: system, solve and energy terms; returns (solution, terms).

        ``eta_old``, ``eta_new`` are η at tⁿ and tⁿ⁺¹, on which the identity
        measures the kinetic energy (default: the domain's η, a still domain).
        """
        system = self.system(history, domain, scheme, dt, times, interface)
        solution = self.solve(system)
        eta_old = domain.eta if eta_old is None else eta_old
        eta_new = domain.eta if eta_new is None else eta_new
        return solution, self.identity(system, solution, eta_old, eta_new)

    @abstractmethod
    def wall_velocity(self, state: Any) -> np.ndarray:
        """The wall's u_r of ``state`` as a line vector."""

    @abstractmethod
    def energy(self, state: Any, eta: np.ndarray | None = None,
               eta_z: np.ndarray | None = None) -> dict[str, float]:
        """The fluid's stored energy by ledger column: ``kinetic.fluid`` and what its ends' conditions store
        (``eta_z``: the lumen's d_z of an axially moved domain)."""

    @abstractmethod
    def kinetic_energy(self, state: Any, eta: np.ndarray | None = None, eta_z: np.ndarray | None = None) -> float:
        """½ρ_f ∫ J|u|² on the domain of ``eta`` (and ``eta_z``)."""

    @abstractmethod
    def flow_rate(self, state: Any, eta: np.ndarray | None, z: float, eta_z: np.ndarray | None = None) -> float:
        """Volume flux through the section at z (cm²/s) (the section moved by the lumen's ``eta_z`` when given)."""

    @abstractmethod
    def probe(self, quantity: str, z: float, rhat: float | None = None) -> Any:
        """A function (state, η) → float for a probe, built once per run; called (state, η, η_z) when the
        domain moves axially (the lumen's d_z, no-slip at a thick band).

        ``u_z``, ``u_r``, ``p`` at the reference point (z, r̂) of the ALE map
        (it moves with the channel), or ``flow_rate`` through the section z.
        """

    @abstractmethod
    def velocity(self, state: Any, eta: np.ndarray | None, z, r, eta_z: np.ndarray | None = None) -> np.ndarray:
        """(u_z, u_r) at physical points, a (2, n) array (of the domain moved axially by ``eta_z`` when given)."""

    @abstractmethod
    def pressure(self, state: Any, eta: np.ndarray | None, z, r, eta_z: np.ndarray | None = None) -> np.ndarray:
        """Pressure at physical points (of the domain moved axially by ``eta_z`` when given)."""

    def wall_shear(self, state: Any, eta: np.ndarray | None = None, eta_z: np.ndarray | None = None) -> np.ndarray:
        """The wall shear stress τ_w = −t·2μD(u)n on the lumen (dyn/cm²) as a line vector: t the wall's unit
        tangent downstream, n the fluid's outward unit normal (positive where the flow near the wall runs
        towards z = L), on the domain of ``eta`` (moved axially by ``eta_z`` when given).

        A fluid without it writes no wall shear stress (the default: :func:`gives_wall_shear` is False).
        """
        raise NotImplementedError(f"{type(self).__name__} gives no wall shear stress")

    @abstractmethod
    def snapshot(self, state: Any, eta: np.ndarray | None = None, eta_z: np.ndarray | None = None) -> tuple:
        """(points (n, 2) in the deformed channel, triangles, point data); ``eta_z`` the lumen's d_z of an
        axially moved domain."""


def gives_wall_shear(fluid: Fluid) -> bool:
    """True when ``fluid``'s class gives :meth:`Fluid.wall_shear` (the default refuses; so does a class registered
    as a Fluid without deriving from it)."""
    return getattr(type(fluid), "wall_shear", Fluid.wall_shear) is not Fluid.wall_shear
