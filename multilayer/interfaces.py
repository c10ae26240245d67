"""Abstract interfaces: Layer (thin or thick), Fluid, Coupler — and the spaces and values they exchange.

The core assembles any wall from the contributions of its layers without
knowing a concrete model.  A layer contributes

* its mass, damping and stiffness matrices (:class:`LayerMatrices`): these are
  its forms of theory §6 A1 (ρ₁h ∫vψ, b₁, a₁ for a thin layer; ρ₂ ∫V·Ψ, a_S for
  a thick one) and, through them, its energy terms of §4 (½vᵀMv kinetic,
  ½dᵀKd elastic, Δt vᵀCv dissipated);
* its essential boundary conditions (:meth:`Layer.essential_dofs`).

A thin layer lives on an interface line and is given a :class:`LineSpace`
(1D Lagrange on the z-partition; its DOFs are the radial DOFs of the fields
next to it).  A thick layer is a radial band and is given a :class:`BandSpace`
(vector Lagrange restricted to the band, in the numbering of the whole wall).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

import attrs
import numpy as np
import scipy.sparse as sp

from multilayer.loads import is_zero

if TYPE_CHECKING:  # pragma: no cover
    import skfem

    from multilayer.case import Case
    from multilayer.linsolve import SolverStats
    from multilayer.setup import Setup
    from multilayer.state import State
    from multilayer.timescheme import TimeScheme


@attrs.frozen(eq=False)
class LayerMatrices:
    """Mass M, damping C and stiffness K of one layer (symmetric, sparse).

    The layer's energy terms follow from them:

    >>> import scipy.sparse as sp, numpy as np
    >>> m = LayerMatrices(sp.eye(2) * 2.0, sp.csr_matrix((2, 2)), sp.eye(2))
    >>> m.kinetic(np.array([1.0, 1.0])), m.elastic(np.array([1.0, 0.0]))
    (2.0, 0.5)
    """

    mass: sp.spmatrix
    damping: sp.spmatrix
    stiffness: sp.spmatrix

    def kinetic(self, v: np.ndarray) -> float:
        """½ vᵀ M v."""
        return 0.5 * float(v @ (self.mass @ v))

    def elastic(self, d: np.ndarray) -> float:
        """½ dᵀ K d."""
        return 0.5 * float(d @ (self.stiffness @ d))

    def dissipation(self, v: np.ndarray, dt: float) -> float:
        """Δt vᵀ C v: energy the layer's viscosity takes in one step."""
        return dt * float(v @ (self.damping @ v))

    def scattered(self, P: sp.spmatrix) -> LayerMatrices:
        """The same forms moved to another numbering: P A Pᵀ."""
        return LayerMatrices(
            (P @ self.mass @ P.T).tocsr(),
            (P @ self.damping @ P.T).tocsr(),
            (P @ self.stiffness @ P.T).tocsr(),
        )


@attrs.frozen(eq=False)
class LineSpace:
    """The 1D space of a thin layer on the interface line r = ``radius``.

    ``basis`` is a scikit-fem basis of 1D Lagrange elements (order of the
    scene) on the z-partition shared by every field of the scene.
    """

    basis: skfem.CellBasis
    radius: float
    length: float
    order: int

    @property
    def z(self) -> np.ndarray:
        """z coordinate of every DOF."""
        return self.basis.doflocs[0]

    @property
    def ndofs(self) -> int:
        return int(self.basis.N)

    @property
    def end_dofs(self) -> np.ndarray:
        """The DOFs at z = 0 and z = L."""
        tol = 1e-9 * self.length
        return np.flatnonzero((self.z < tol) | (self.z > self.length - tol))


@attrs.frozen(eq=False)
class BandSpace:
    """The space of a thick layer: the band ``r_inner < r < r_outer``.

    ``basis`` is a vector (d_z, d_r) Lagrange basis restricted to the band's
    elements; its numbering is that of the whole wall, so matrices assembled
    on it are already global.
    """

    basis: skfem.CellBasis
    r_inner: float
    r_outer: float
    length: float
    order: int

    @property
    def thickness(self) -> float:
        return self.r_outer - self.r_inner

    @property
    def ndofs(self) -> int:
        """Size of the numbering the band's matrices live in: the whole wall's, so (ndofs, ndofs)."""
        return int(self.basis.N)

    @property
    def dofs(self) -> np.ndarray:
        """Every DOF touched by the band."""
        return np.unique(self.basis.element_dofs)

    def side_dofs(self, side: str, component: str | None = None) -> np.ndarray:
        """DOFs on one side of the band: ``"z=0"``, ``"z=L"``, ``"inner"``, ``"outer"``.

        ``component`` is ``"z"``, ``"r"`` or ``None`` (both).
        """
        dofs = self.dofs
        z, r = self.basis.doflocs[:, dofs]
        tol = 1e-9 * max(self.length, self.r_outer)
        where = {
            "z=0": np.abs(z) < tol,
            "z=L": np.abs(z - self.length) < tol,
            "inner": np.abs(r - self.r_inner) < tol,
            "outer": np.abs(r - self.r_outer) < tol,
        }[side]
        picked = dofs[where]
        if component is None:
            return picked
        owned = self.basis.split_indices()[{"z": 0, "r": 1}[component]]
        return np.intersect1d(picked, owned)


class Layer(ABC):
    """A wall layer.  Subclass :class:`ThinLayer` or :class:`ThickLayer`."""

    thin: ClassVar[bool]

    @abstractmethod
    def forms(self, space: Any) -> LayerMatrices:
        """Mass, damping and stiffness on ``space``."""

    def essential_dofs(self, space: Any) -> np.ndarray:
        """DOFs held at zero (in the numbering of ``space``)."""
        return np.zeros(0, dtype=np.int64)


class ThinLayer(Layer):
    """A layer on an interface line; unknown: the radial displacement η(z)."""

    thin = True

    def essential_dofs(self, space: LineSpace) -> np.ndarray:
        """Ends pinned: η(0) = η(L) = 0."""
        return space.end_dofs

    def long_wave_stiffness(self, radius: float | None = None) -> float:
        """C0 (dyn/cm³): the k → 0 limit of the layer's stiffness, 0 if none.

        ``radius`` is the radius of the line the layer sits on, for models
        whose coefficients depend on it.
        """
        return 0.0


class ThickLayer(Layer):
    """A radial band of the wall; unknown: the displacement d = (d_z, d_r)."""

    thin = False
    #: radial extent H of the band (cm)
    thickness: float

    def essential_dofs(self, space: BandSpace) -> np.ndarray:
        """Ends clamped: d = 0 at z = 0 and z = L."""
        return np.union1d(space.side_dofs("z=0"), space.side_dofs("z=L"))


@attrs.frozen(eq=False)
class Domain:
    """The fluid domain of one step, explicit in time: line vectors on the interface line.

    ``eta`` is the wall displacement of the geometry the step is assembled
    on (J_m, ∇^η); ``velocity`` the wall velocity c that moves the domain
    during the step (∂_t J = c/R, ALE velocity w = c r̂/R).
    """

    eta: np.ndarray
    velocity: np.ndarray

    @classmethod
    def still(cls, n: int) -> Domain:
        """The reference channel at rest (n line DOFs)."""
        return cls(np.zeros(n), np.zeros(n))


@attrs.frozen(eq=False)
class Interface:
    """Terms a coupler adds on the fluid's wall u_r rows, in line numbering: R v̄ − r.

    In the kinematically coupled scheme R = (α₀/β₀) M/Δt with M = ρ₁h∫vψ the
    thin layer's mass (the Robin term) and r the old thin-layer inertia.
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
    def setup(self, length: float, radius: float, nz: int, nr: int, order: int = 2, grading: float = 1.0,
              wall: str = "coupled", solver: str = "superlu", line: LineSpace | None = None) -> Any:
        """Discretize for a wall mode ``coupled``, ``rigid`` or ``prescribed``.

        A fluid whose ``setup`` also takes a keyword ``reuse`` (a
        :class:`multilayer.linsolve.Reuse`) is given the case's
        ``[solver] reuse`` policy; one without it is set up as before.
        """

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
    @abstractmethod
    def stats(self) -> SolverStats:
        """Factorizations and solves of the fluid's own systems."""

    @property
    @abstractmethod
    def timings(self) -> dict[str, float]:
        """Seconds spent in ``assembly`` and ``ledger`` so far."""

    @abstractmethod
    def initial_state(self) -> Any:
        """The fluid at rest."""

    @abstractmethod
    def system(self, history: Sequence[Any], domain: Domain, scheme: TimeScheme, dt: float,
               p_in: float = 0.0, p_out: float = 0.0, interface: Interface | None = None) -> Any:
        """The linear system of one step on ``domain`` (history: the states at tⁿ, t^{n−1}, ...)."""

    @abstractmethod
    def matrix(self, system: Any) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray, np.ndarray]:
        """(A, b, fixed DOFs, their values) of ``system``: A x̄ = b on the free DOFs."""

    @abstractmethod
    def solve(self, system: Any) -> Any:
        """Solve ``system``; the result has ``state`` (the new state) and ``mean`` (the test-level x̄)."""

    @abstractmethod
    def prescribe(self, system: Any, wall_velocity: np.ndarray) -> Any:
        """``system`` with the wall's u_r prescribed to ``wall_velocity`` (a line vector; prescribed mode).

        Only the Dirichlet data change: a Dirichlet–Neumann coupler iterates on
        it without refactorizing.
        """

    @abstractmethod
    def advance(self, system: Any, mean: np.ndarray) -> Any:
        """The solution of ``system`` from its test-level unknowns x̄ solved elsewhere."""

    @abstractmethod
    def identity(self, system: Any, solution: Any, eta_old: np.ndarray, eta_new: np.ndarray) -> dict[str, float]:
        """The step's energy terms (see :meth:`multilayer_plugins.channel.step.FluidStep.identity`)."""

    @abstractmethod
    def reaction(self, system: Any, mean: np.ndarray) -> np.ndarray:
        """The fluid's residual on the wall's u_r rows as a line vector: minus its force on the wall."""

    def step(self, history: Sequence[Any], domain: Domain, scheme: TimeScheme, dt: float, p_in: float = 0.0,
             p_out: float = 0.0, interface: Interface | None = None, eta_old: np.ndarray | None = None,
             eta_new: np.ndarray | None = None) -> tuple[Any, dict[str, float]]:
        """One step: system, solve and energy terms; returns (solution, terms).

        ``eta_old``, ``eta_new`` are η at tⁿ and tⁿ⁺¹, on which the identity
        measures the kinetic energy (default: the domain's η, a still domain).
        """
        system = self.system(history, domain, scheme, dt, p_in, p_out, interface)
        solution = self.solve(system)
        eta_old = domain.eta if eta_old is None else eta_old
        eta_new = domain.eta if eta_new is None else eta_new
        return solution, self.identity(system, solution, eta_old, eta_new)

    @abstractmethod
    def wall_velocity(self, state: Any) -> np.ndarray:
        """The wall's u_r of ``state`` as a line vector."""

    @abstractmethod
    def kinetic_energy(self, state: Any, eta: np.ndarray | None = None) -> float:
        """½ρ_f ∫ J|u|² on the domain of ``eta``."""

    @abstractmethod
    def flow_rate(self, state: Any, eta: np.ndarray | None, z: float) -> float:
        """Volume flux through the section at z (cm²/s)."""

    @abstractmethod
    def probe(self, quantity: str, z: float, rhat: float | None = None) -> Any:
        """A function (state, η) → float for a probe, built once per run.

        ``u_z``, ``u_r``, ``p`` at the reference point (z, r̂) of the ALE map
        (it moves with the channel), or ``flow_rate`` through the section z.
        """

    @abstractmethod
    def velocity(self, state: Any, eta: np.ndarray | None, z, r) -> np.ndarray:
        """(u_z, u_r) at physical points, a (2, n) array."""

    @abstractmethod
    def pressure(self, state: Any, eta: np.ndarray | None, z, r) -> np.ndarray:
        """Pressure at physical points."""

    @abstractmethod
    def snapshot(self, state: Any, eta: np.ndarray | None = None) -> tuple:
        """(points (n, 2) in the deformed channel, triangles, point data)."""


@attrs.frozen
class StepReport:
    """The energy terms of one step (theory §7), by column name, as a coupler reports them.

    ``stored`` is the energy at tⁿ⁺¹ as the scheme's identity measures it
    (kinetic and elastic, per part), ``work`` what the loads put in,
    ``dissipation`` what viscosity, the scheme and the explicit geometry
    take out (a geometric remainder may be negative).  The runner closes
    the ledger from them: Eⁿ⁺¹ − Eⁿ − work + dissipation = 0.
    ``diagnostics`` are extra columns (e.g. each sub-step's own residual).
    """

    stored: Mapping[str, float] = attrs.field(factory=dict)
    work: Mapping[str, float] = attrs.field(factory=dict)
    dissipation: Mapping[str, float] = attrs.field(factory=dict)
    diagnostics: Mapping[str, float] = attrs.field(factory=dict)


class SchemeFailure(Exception):
    """A coupler cannot go on (e.g. sub-iterations that do not converge); the message says where and when."""


class Coupler(ABC):
    """A time-stepping scheme: a pure stepper over a frozen setup.

    ``evolve(setup, state0)`` yields ``(state, report)`` after every step:
    the new :class:`~multilayer.state.State` (a value; nothing is mutated)
    and the step's :class:`StepReport`.  The runner writes rows, probes
    and snapshots from them and closes the energy ledger.
    """

    #: the loads (keys of ``[loads]``) this coupler applies; any other must be left at 0
    loads: ClassVar[tuple[str, ...]] = ()
    #: the time schemes (:data:`multilayer.timescheme.SCHEMES`) it offers; its ``scheme`` parameter
    schemes: ClassVar[tuple[str, ...]] = ("backward-euler",)

    def __init__(self, scheme: str = "backward-euler"):
        from multilayer.timescheme import SCHEMES

        if scheme not in self.schemes:
            raise ValueError(f"scheme {scheme!r} is not offered; choose one of {', '.join(self.schemes)}")
        self.scheme: TimeScheme = SCHEMES[scheme]

    def check_case(self, case: Case) -> list[str]:
        """Reasons this coupler cannot run ``case`` (empty when it can).

        Called by the case validator, so ``multilayer validate`` reports them.
        The default rejects a non-zero load that the coupler would ignore.
        """
        name = getattr(self, "name", type(self).__name__)
        return [f"loads.{key} is set, but {name} does not apply it (it applies: {', '.join(self.loads) or 'none'})"
                for key in ("inlet", "outlet", "external", "interface")
                if key not in self.loads and not is_zero(getattr(case.loads, key))]

    def fluid_wall(self, case: Case) -> str:
        """How the fluid sees the wall: ``coupled``, ``rigid`` or ``prescribed``."""
        return "coupled"

    def initial_state(self, setup: Setup) -> State:
        """The state at t = 0 (the case's initial wall, the fluid at rest)."""
        return setup.initial_state()

    @abstractmethod
    def energy(self, setup: Setup, state: State) -> dict[str, float]:
        """The stored energy of ``state`` by part, as this scheme's identity measures it."""

    @abstractmethod
    def evolve(self, setup: Setup, state: State) -> Iterator[tuple[State, StepReport]]:
        """Advance from ``state`` step by step, yielding the new state and the step's report."""
