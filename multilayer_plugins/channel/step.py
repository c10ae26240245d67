"""The fluid step on one domain: the linear Oseen-type system for (ū, p̄), its solve, its energy identity.

On the reference channel, with the ALE fields of the step's domain (η_m, and
the domain velocity c that moves it) and a time scheme with coefficients
α, β (:mod:`multilayer.numerics.timescheme`), find the test-level unknowns
ū = Σβ_k u^{n+1−k} and p̄ with u_r = 0 on the axis, inlet and outlet, u_z = 0
on the wall, such that

    ρ_f/Δt mass_J(Σ α_k u^{n+1−k}, q) + ρ_f advection_skew(ū, q) + ρ_f moving_domain(ū, q)
  + 2μ viscous(ū, q) − ∫ J p̄ ∇^η·q + ∫ J π ∇^η·ū + [R v̄ − r]·ψ
  + Σ_e R_e (∫_Γe J q·n)(∫_Γe J ū·n) [+ Σ_e ½ρ_f ∫_Γe J κ(a·n) ū·q] = − Σ_e P_e ∫_Γe J q·n,

every integral in the geometry's measure (the ``navier-stokes`` fluid adds SUPG
and grad-div to the left, and SUPG's old levels to the right:
:mod:`multilayer_plugins.channel.stabilization`), where each open end e (inlet,
outlet) has the mean pressure p̄_e = P_e + R_e Q̄_e its condition gives
(:mod:`multilayer_plugins.channel.ends`; a prescribed pressure has R_e = 0),
and the bracket is the convective term of static-pressure ends
(:mod:`multilayer_plugins.channel.end_convection`).
An end that prescribes its flux instead (a flow rate) has an unknown mean
pressure λ_e, appended after (ū, p̄): its term λ_e ∫_Γe J q·n on the left
and the row ∫_Γe J ū·n = Q̄_e (the test level of u^{n+1}'s prescribed
flux), so the unknowns are x̄ = (ū, p̄, λ).
The old levels go to the right-hand side, so the matrix is
(α₀/β₀) ρ_f/Δt mass_J + the rest (a backward-Euler matrix of step Δt β₀/α₀).
[R v̄ − r] is what a coupler puts on the wall's u_r rows (line numbering):
the thin layer's inertia as a Robin term in the kinematically coupled scheme
(theory §6 A2), nothing in a monolithic solve, which adds the wall itself.

Wall modes:

``coupled``
    the wall's u_r DOFs are unknowns (ū_r = v̄ on Γ);
``no-slip``
    the wall's u_r and u_z DOFs are unknowns, but u_z at Γ's corners (a
    fluid on a thick band: a monolithic coupler adds the band's d_z rows);
``rigid``
    u = 0 on the wall and the domain never moves;
``prescribed``
    ū_r = c on the wall (Dirichlet): the wall moves as given.

The matrix is assembled into a sparsity pattern fixed at setup
(:class:`multilayer.numerics.assembly.pattern.Pattern`).  On a rigid wall only the
advection term changes between steps, and a Stokes fluid on a rigid wall
has a constant matrix: it is factorized once per Δt.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np
import scipy.sparse as sp

from multilayer.boundary.contract import BoundaryCondition, EndTraction
from multilayer.fluid.contract import ENDS, GIVEN_WALLS, Domain, Interface
from multilayer.geometry.spaces import prolongation_dofs
from multilayer.numerics.assembly.batched import BatchedForm, SkewPart
from multilayer.numerics.assembly.pattern import Pattern
from multilayer.numerics.linsolve import (
    Factorized,
    Reuse,
    ReusingSolver,
    SolverStats,
    factorize,
)
from multilayer.numerics.timescheme import TimeScheme, levels
from multilayer_plugins.channel import forms
from multilayer_plugins.channel.ale import ALEFields, deformation, volume_element
from multilayer_plugins.channel.channel import Channel
from multilayer_plugins.channel.ends import Ends
from multilayer_plugins.channel.extension import AxialExtension
from multilayer_plugins.channel.ledger import Quadrature
from multilayer_plugins.channel.stabilization import Stabilization, Stabilized

WALL_MODES = ("coupled", "no-slip", "rigid", "prescribed")


@attrs.frozen(eq=False)
class FluidState:
    """Velocity and pressure DOFs on the reference channel, and the wall velocity.

    ``v`` is the wall's u_r as a vector of the interface line's space:
    the kinematic condition u = v e_r on Γ, in the thin layer's numbering.
    ``p`` is the pressure of the step that made the state (at the scheme's
    test level: the midpoint for Crank–Nicolson).
    """

    u: np.ndarray
    p: np.ndarray
    v: np.ndarray
    #: the state of each end's condition (None for one without state), by end
    ends: Mapping[str, Any] = attrs.field(factory=dict)


@attrs.frozen(eq=False)
class FluidSystem:
    """One step's linear system: matrix (CSR data in the fixed pattern), right-hand side, what it was built from.

    ``matrix`` and ``rhs`` hold the fluid's own equations plus the coupler's
    interface terms; ``own`` is the data without the interface terms (for the
    wall reaction).  ``fixed`` are the Dirichlet DOFs with values ``fixed_values``.
    ``data`` and ``own`` are buffers the step keeps for the run (the
    pattern's filler's, and a copy with the interface terms): they hold this
    system's matrix until the next :meth:`FluidStep.system`, so a system is
    solved in the step that assembles it (every coupler does).
    """

    data: np.ndarray
    own: np.ndarray
    rhs: np.ndarray
    own_rhs: np.ndarray
    fixed: np.ndarray
    fixed_values: np.ndarray
    fields: ALEFields
    domain: Domain
    scheme: TimeScheme
    dt: float
    history: tuple[FluidState, ...]
    #: each end's mean pressure over the step, p̄ = P + R Q̄
    tractions: Mapping[str, EndTraction]
    interface: Interface | None
    #: what a constant matrix is cached by: the mass coefficient and the implicit ends' resistances
    key: tuple[float, ...]
    #: what stands for this system's matrix in the solver (kept by ``attrs.evolve``: a prescribed wall
    #: velocity changes the right-hand side only, so the same factors serve)
    token: object = attrs.field(factory=object)
    #: the step's residual-based stabilization (SUPG, grad-div), None when off or without advection
    stabilized: Stabilized | None = None


@attrs.frozen(eq=False)
class Solution:
    """The solved test-level unknowns x̄ = (ū, p̄, λ) and the new state."""

    mean: np.ndarray
    state: FluidState


class FluidStep:
    """The discretization of one fluid on one channel for one wall mode.

    Parameters
    ----------
    channel : Channel
        Reference mesh, spaces and DOF sets.
    density, viscosity : float
        ρ_f (g/cm³) and μ (poise).
    advection : bool
        True for Navier–Stokes, False for Stokes (the moving-domain term stays).
    wall : str
        ``"coupled"``, ``"rigid"`` or ``"prescribed"``.
    solver : str
        A backend of :mod:`multilayer.numerics.linsolve`.
    reuse : Reuse
        When a changing matrix is refactorized (:class:`multilayer.numerics.linsolve.Reuse`).
    ends : mapping
        The condition of each open end (``inlet``, ``outlet``); a missing end is traction-free.
    backflow : float or None
        None: the ends' pressures are total pressures (the skew advection's natural condition); β ≥ 0:
        static-pressure ends with the backflow term of strength β (Navier–Stokes only:
        :mod:`multilayer_plugins.channel.end_convection`).
    interface_block : bool
        True when the coupler's interface matrix R couples every two DOFs of
        the wall line (a wall step condensed on Γ): the pattern then holds the
        whole line × line block, not only the entries neighbours share.
    held : array of int
        The wall line's DOFs the wall holds at rest (a band whose inner face
        slides radially fixed): the wall's u_r is 0 there, as at the ends.
    stabilization : Stabilization, optional
        SUPG and grad-div (:mod:`multilayer_plugins.channel.stabilization`); only with advection.
    """

    def __init__(self, channel: Channel, density: float, viscosity: float, advection: bool,
                 wall: str = "coupled", solver: str = "superlu", reuse: Reuse = Reuse(),
                 ends: Mapping[str, BoundaryCondition] | None = None, backflow: float | None = None,
                 interface_block: bool = False, held: np.ndarray | None = None,
                 stabilization: Stabilization | None = None):
        if wall not in WALL_MODES:
            raise ValueError(f"wall mode {wall!r} is not one of {WALL_MODES}")
        self.channel = channel
        self.density = density
        self.viscosity = viscosity
        self.advection = advection
        self.stabilization = stabilization if advection else None
        self.wall = wall
        self.solver = solver
        self.stats = SolverStats()
        self._solver = ReusingSolver(self.stats, solver, reuse)
        self.assembly_s = 0.0
        self.ledger_s = 0.0

        ub, pb = channel.velocity, channel.pressure
        nu = channel.nu
        self._uu = BatchedForm(ub)
        self._pu = BatchedForm(ub, pb)
        uu, pu = (self._uu.rows, self._uu.cols), (self._pu.rows + nu, self._pu.cols)
        self.ends = Ends(channel, ends or {}, density, backflow if advection else None)
        if wall in GIVEN_WALLS and len(self.ends.multipliers) == len(ENDS):
            # the incompressibility dilemma: a fluid whose wall it does not move has no volume to give
            raise ValueError(f"a flow rate at both ends of a fluid on a {wall} wall fixes its volume balance twice "
                             f"and leaves the level of the pressure free: prescribe a pressure at one end")
        n = self.ndofs
        #: the velocity DOF of each line DOF: where the wall's u_r sits
        self.interface_dofs = prolongation_dofs(channel.prolongation)
        block = []
        if interface_block:
            if wall != "coupled":
                raise ValueError(f"a dense interface block needs the coupled wall mode, not {wall!r}")
            rows, cols = np.meshgrid(self.interface_dofs, self.interface_dofs, indexing="ij")
            block.append((rows.ravel(), cols.ravel()))
        self.pattern = Pattern((n, n), [uu, pu, pu[::-1], *self.ends.entries(), *block])
        self.ends.place(self.pattern)
        # the data array of a step: velocity block, divergence rows, and their negated transpose
        self._fill = self.pattern.filler([self.pattern.slots(*uu), self.pattern.slots(*pu),
                                          self.pattern.slots(*pu[::-1])], scales=[1.0, 1.0, -1.0])
        self._extension: AxialExtension | None = None  # built at the first axially moving domain
        #: the velocity DOF of the wall's u_z at each line DOF (the same node's other component)
        comp_z, comp_r = channel.velocity.split_indices()
        self.interface_z_dofs = comp_z[np.searchsorted(comp_r, self.interface_dofs)]
        fixed = [channel.normal_r,
                 self.interface_z_dofs[list(channel.ends)] if wall == "no-slip" else channel.wall_z]
        if wall in ("rigid", "prescribed"):
            fixed.append(channel.wall_r)
        elif held is not None:
            fixed.append(self.interface_dofs[np.asarray(held, dtype=np.int64)])
        self.fixed = np.unique(np.concatenate(fixed))
        self.free = np.setdiff1d(np.arange(n), self.fixed)
        self._block_ff = self.pattern.block(self.free, self.free)
        self._block_fd = self.pattern.block(self.free, self.fixed)

        self._quadrature = Quadrature(self._uu, density)
        self._rigid = ALEFields.rigid(channel)
        self._static: dict[float, tuple] = {}  # rigid wall: element data of the geometry part, per mass coefficient
        self._constant: dict[float, tuple[np.ndarray, Factorized]] = {}  # Stokes, rigid: data and LU
        self._interface_slots: tuple | None = None
        self._buffers: tuple[np.ndarray, np.ndarray] | None = None
        # the data with the interface terms (and the free block's values, kept by the block): kept for the run,
        # so only the latest system's matrix is valid — every coupler solves a system in the step that assembles it
        self._with_interface: np.ndarray | None = None

    @property
    def extension(self) -> AxialExtension:
        """The harmonic extension of the lumen's d_z (factorized at its first use: only under no-slip)."""
        if self._extension is None:
            self._extension = AxialExtension(self.channel)
        return self._extension

    def fields(self, domain: Domain, dt: float, position: float) -> ALEFields:
        """The ALE fields of ``domain`` in a step of ``dt`` whose geometry sits at ``position`` (radial or axial
        map)."""
        if self.wall == "rigid":
            return self._rigid
        if domain.eta_z is None:
            return ALEFields.at(self.channel, domain.eta, domain.velocity, dt, position)
        return ALEFields.moving(self.channel, self.extension, domain.eta, domain.velocity, domain.eta_z,
                                domain.velocity_z, dt, position)

    @property
    def ndofs(self) -> int:
        """Unknowns of the step: (u, p) and a multiplier λ_e per end that prescribes its flux."""
        return self.channel.ndofs + len(self.ends.multipliers)

    @property
    def constant_matrix(self) -> bool:
        """True when the matrix never changes for a given Δt: Stokes on a rigid wall."""
        return self.wall == "rigid" and not self.advection

    # -- assembly -------------------------------------------------------------
    # The forms of a step fall in three parts (docs/performance.md, "Assembly"):
    # constant for the run (the reference jets, the sparsity pattern and its slots,
    # the end-load vectors: built in __init__), geometry-only (mass_J, viscous,
    # pressure_divergence: they depend on η alone) and state (moving_domain on
    # the domain velocity, advection_skew on uⁿ − w, assembled as SkewPart(advection):
    # the convective kernel once, then ½(K − Kᵀ)).  The geometry part is
    # kept where η never changes (a rigid wall); on a moving wall it changes
    # every step and is assembled with the state part in one pass.
    def _geometry_terms(self, fields: ALEFields, mass_coefficient: float) -> list:
        kw = fields.forms_kwargs()
        terms = [(mass_coefficient, forms.mass_J, kw), (2.0 * self.viscosity, forms.viscous, kw)]
        if fields.hoop is not None:
            terms.append((2.0 * self.viscosity * fields.hoops, forms.hoop_viscous, fields.hoop_kwargs()))
        return terms

    @staticmethod
    def _divergence_terms(fields: ALEFields) -> list:
        terms = [(1.0, forms.pressure_divergence, fields.forms_kwargs())]
        if fields.hoop is not None:
            terms.append((float(fields.hoops), forms.hoop_divergence, fields.hoop_kwargs()))
        return terms

    def _state_terms(self, fields: ALEFields, a: np.ndarray | None) -> list:
        terms = []
        if np.any(fields.dJdt):
            terms.append((self.density, forms.moving_domain, {"dJdt": fields.dJdt}))
        if a is not None:
            terms.append((self.density, SkewPart(forms.advection), dict(fields.forms_kwargs(), a=a)))
        return terms

    def _element_data(self, fields: ALEFields, mass_coefficient: float, a: np.ndarray | None):
        """Element matrices of the velocity block (every term) and of the divergence block."""
        state = self._state_terms(fields, a)
        if self.wall != "rigid":
            if self._buffers is None:  # the element data of every step goes here: no fresh pages per step
                self._buffers = (np.empty(self._uu.shape), np.empty(self._pu.shape))
            geometry = self._geometry_terms(fields, mass_coefficient)
            div = self._pu.data(self._divergence_terms(fields), out=self._buffers[1])
            return self._uu.data(geometry + state, out=self._buffers[0]), div
        if mass_coefficient not in self._static:
            self._static[mass_coefficient] = (
                self._uu.data(self._geometry_terms(fields, mass_coefficient)),
                self._pu.data(self._divergence_terms(fields)))
        velocity, div = self._static[mass_coefficient]
        return (velocity + self._uu.data(state) if state else velocity), div

    def _interface_terms(self, interface: Interface | None) -> list[tuple[np.ndarray, np.ndarray]]:
        """(slots, values) of the coupler's matrix R on the wall u_r DOFs; slots looked up once per R."""
        if interface is None:
            return []
        if self._interface_slots is None or self._interface_slots[0] is not interface.matrix:
            R = sp.coo_matrix(interface.matrix)
            rows, cols = self.interface_dofs[R.row], self.interface_dofs[R.col]
            self._interface_slots = (interface.matrix, self.pattern.slots(rows, cols), R.data)
        return [self._interface_slots[1:]]

    def _check(self, domain: Domain, interface: Interface | None, history: Sequence[FluidState]) -> None:
        nline = self.channel.line.ndofs
        if domain.eta.shape != (nline,) or domain.velocity.shape != (nline,):
            raise ValueError(f"η and the domain velocity must be vectors of the interface line ({nline} DOFs)")
        if self.wall == "rigid" and (np.any(domain.eta) or np.any(domain.velocity)):
            raise ValueError("a rigid wall does not move: pass η = v = 0")
        if self.wall != "coupled" and interface is not None:
            raise ValueError(f"interface terms only enter the coupled wall mode, not {self.wall!r}")
        if interface is not None and (interface.matrix.shape != (nline, nline) or interface.rhs.shape != (nline,)):
            raise ValueError(f"the interface terms must be a {nline} × {nline} matrix and a vector on the line")
        if (domain.eta_z is None) != (domain.velocity_z is None):
            raise ValueError("an axially moving domain needs both the lumen's d_z and its velocity")
        if domain.eta_z is not None and (domain.eta_z.shape != (nline,) or domain.velocity_z.shape != (nline,)):
            raise ValueError(f"the lumen's d_z and its velocity must be vectors of the interface line ({nline} DOFs)")
        if self.wall == "prescribed":
            self._check_ends(domain.velocity)
            if domain.velocity_z is not None:
                self._check_ends(domain.velocity_z)
        if not history:
            raise ValueError("the fluid step needs the state at tⁿ")

    def _check_ends(self, c: np.ndarray) -> None:
        ends = list(self.channel.ends)
        if np.max(np.abs(c[ends])) > 1e-12 * max(np.max(np.abs(c)), 1e-300):
            raise ValueError("a prescribed wall motion must vanish at z = 0 and z = L (u_r = 0 there)")

    def system(self, history: Sequence[FluidState], domain: Domain, scheme: TimeScheme, dt: float,
               times: tuple[float, float], interface: Interface | None = None) -> FluidSystem:
        """Assemble the step [tⁿ, tⁿ⁺¹] = ``times`` on ``domain`` (see the module docstring).

        ``history`` holds uⁿ, u^{n−1}, ... (newest first; padded with the
        oldest when a multistep scheme wants more).  Each end's condition gives
        its mean pressure over the scheme's window of the step
        (:mod:`multilayer_plugins.channel.ends`).
        """
        if not dt > 0.0:
            raise ValueError(f"time step must be > 0 s, got {dt!r}")
        self._check(domain, interface, history)
        t0 = time.perf_counter()
        ch = self.channel
        hist = tuple(levels(history[0], history[1:], scheme.old_levels))
        fields = self.fields(domain, dt, scheme.geometry_position)
        mass_coefficient = scheme.inertia * self.density / dt
        tractions = self.ends.tractions(times, dt, scheme, hist, fields)
        key = (mass_coefficient, *self.ends.resistances(tractions))
        constant = self._constant.get(key) if self.constant_matrix else None
        stabilized = None
        if constant is not None:
            own = constant[0]
        else:
            a = advecting = None
            if self.advection:
                advecting = scheme.extrapolate([s.u for s in hist])
                a = self._uu.trial_jets(advecting, values_only=True)
                a[1] -= fields.wr
                if fields.wz is not None:
                    a[0] -= fields.wz
            velocity, div = self._element_data(fields, mass_coefficient, a)
            transposed = div
            if self.stabilization is not None:  # SUPG's and grad-div's element matrices onto the Galerkin ones
                stabilized = self.stabilization.step(fields, a, mass_coefficient, dt)
                velocity = velocity + stabilized.velocity_block(self._uu.shape).ravel()
                # SUPG's ∇p̄ on the velocity rows: into the slots of −divᵀ, which the filler scales by −1
                transposed = div - stabilized.pressure_block(self._pu.shape[0]).ravel()
            own = self._fill(velocity, div, transposed)
            self.ends.add_matrix(own, tractions, fields, advecting)
        data = own
        if interface is not None:  # the coupler's few interface entries added to a copy, not a refill
            if self._with_interface is None:
                self._with_interface = np.empty_like(own)
            data = self._with_interface  # kept for the run: the latest system's only (see solve)
            np.copyto(data, own)
            for slots, values in self._interface_terms(interface):
                np.add.at(data, slots, values)
        own_rhs = np.zeros(self.ndofs)
        h = scheme.history([s.u for s in hist])
        own_rhs[: ch.nu] = -(self.density / dt) * self._uu.apply([(1.0, forms.mass_J, {"J": fields.J})], h)
        if stabilized is not None:
            own_rhs[: ch.nu] += stabilized.rhs(h)
        self.ends.add_rhs(own_rhs, tractions, fields)
        rhs = own_rhs
        if interface is not None:
            rhs = own_rhs.copy()
            rhs[: ch.nu] += ch.prolongation @ interface.rhs
        fixed_values = np.zeros(self.ndofs)
        if self.wall == "prescribed":
            fixed_values[: ch.nu] = ch.prolongation @ domain.velocity
            fixed_values[ch.normal_r] = 0.0
            if domain.velocity_z is not None:  # no-slip: the wall's u_z is its axial velocity
                fixed_values[self.interface_z_dofs] = domain.velocity_z
        self.assembly_s += time.perf_counter() - t0
        return FluidSystem(data, own, rhs, own_rhs, self.fixed, fixed_values[self.fixed], fields, domain, scheme,
                           dt, hist, tractions, interface, key, stabilized=stabilized)

    # -- solving --------------------------------------------------------------
    def solve(self, system: FluidSystem) -> Solution:
        """Eliminate the Dirichlet DOFs and solve.

        A constant matrix is factorized once per Δt; a changing one goes to
        the :class:`~multilayer.numerics.linsolve.ReusingSolver` (a fresh factorization,
        or GMRES preconditioned by an earlier one; the same system again (its
        ``token``: sub-iterations change only the wall's values) reuses its own
        factors).
        """
        t0 = time.perf_counter()
        rhs = system.rhs[self.free]
        if system.fixed_values.any():  # only a prescribed wall's ū_r is not zero: no block to build otherwise
            rhs -= self._block_fd.matrix(system.data) @ system.fixed_values
        self.assembly_s += time.perf_counter() - t0
        x = np.zeros(self.ndofs)
        x[self.fixed] = system.fixed_values
        if self.constant_matrix:
            key = system.key
            if key not in self._constant:
                self._constant[key] = (system.own.copy(), factorize(self._block_ff.matrix(system.data), self.stats,
                                                             self.solver))
            x[self.free] = self._constant[key][1].solve(rhs)
        else:
            A = self._block_ff.matrix(system.data, keep=True)
            x[self.free] = self._solver.solve(A, rhs, key=system.token)
        return self.advance(system, x)

    @property
    def last_matrix(self) -> sp.spmatrix | None:
        """The latest changing matrix solved (free DOFs), None before the first or for a constant matrix."""
        return self._solver.last

    def prescribe(self, system: FluidSystem, wall_velocity: np.ndarray,
                  wall_velocity_z: np.ndarray | None = None) -> FluidSystem:
        """The same system with the wall's ū_r prescribed to ``wall_velocity`` (prescribed mode), and its ū_z
        to ``wall_velocity_z`` when given (no-slip).

        The matrix is shared, so :meth:`solve` reuses its factorization: a
        sub-iterated coupler pays one factorization per step.
        """
        if self.wall != "prescribed":
            raise ValueError(f"only a prescribed wall takes a wall velocity, not {self.wall!r}")
        self._check_ends(wall_velocity)
        values = np.zeros(self.ndofs)
        values[: self.channel.nu] = self.channel.prolongation @ wall_velocity
        values[self.channel.normal_r] = 0.0
        if wall_velocity_z is not None:
            self._check_ends(wall_velocity_z)
            values[self.interface_z_dofs] = wall_velocity_z
        return attrs.evolve(system, fixed_values=values[self.fixed])

    def advance(self, system: FluidSystem, mean: np.ndarray) -> Solution:
        """The new state from the solved x̄ = (ū, p̄, λ): u^{n+1} from the scheme, v its wall trace, the ends'
        states advanced with their tractions as solved (a flow-rate end's mean pressure λ)."""
        nu = self.channel.nu
        u = system.scheme.new_level(mean[:nu], [s.u for s in system.history])
        tractions = self.ends.resolve(system.tractions, mean)
        ends = self.ends.advance(tractions, self.ends.fluxes(mean[:nu], system.fields), system.dt,
                                 system.scheme, [s.ends for s in system.history])
        state = FluidState(u, mean[nu:self.channel.ndofs].copy(), self.channel.wall_trace(u), ends)
        return Solution(mean, state)

    def reaction(self, system: FluidSystem, mean: np.ndarray, axial: bool = False) -> np.ndarray:
        """The fluid's own residual A x̄ − b on the wall's u_r rows (u_z rows if ``axial``), as a line vector.

        It is minus the force the fluid exerts on the wall over the step,
        tested with each line basis function (dyn/cm per unit depth).
        """
        residual = self.pattern.matrix(system.own) @ mean - system.own_rhs
        if axial:
            return residual[self.interface_z_dofs]
        return self.channel.restriction @ residual[: self.channel.nu]

    # -- the energy identity ----------------------------------------------------
    def identity(self, system: FluidSystem, solution: Solution, eta_old: np.ndarray,
                 eta_new: np.ndarray, axial: tuple[np.ndarray, np.ndarray] | None = None) -> dict[str, float]:
        """Every term of the step's energy identity, from quadrature of the fields and the load vectors.

        Testing the step with x̄ (q_J(x) = ½ρ_f∫J|x|², E the scheme's stored energy):

            E(J^{n+1}) − E(Jⁿ) + numerical + viscous − G + interface = work,
            G = stored(q_{J^{n+1}−J_m}) − stored_old(q_{Jⁿ−J_m}) − Δt q_{∂_tJ}(ū)

        G is the geometric remainder of the explicit domain (J_m the step's
        geometry, ∂_t J = c/R its velocity); it vanishes when J_m = Jⁿ and
        ∂_t J = (J^{n+1} − Jⁿ)/Δt, the kinematically coupled scheme's choice.
        ``interface`` = Δt v̄·(R v̄ − r) is the power handed to the coupler's
        interface terms; ``wall.work`` the power of a prescribed wall.
        Under an axial mesh motion ``axial`` holds the lumen's d_z at tⁿ and
        tⁿ⁺¹: the kinetic energies are weighted by the volume elements of the
        axially moved domains.

        Where each term comes from: the kinetic, numerical and geometric
        terms and the viscous dissipation by quadrature of the fields at the
        assembly's points (:class:`~multilayer_plugins.channel.ledger.Quadrature`,
        weights J^{n+1}, Jⁿ, J^{n+1} − J_m, ∂_t J — never the matrix that was
        solved); the end fluxes from the assembled load vectors (the work of
        the loads is their right-hand side tested with ū); the interface and
        wall powers from the coupler's data.  docs/performance.md, "The ledger".
        """
        t0 = time.perf_counter()
        ch, S, dt, fields = self.channel, system.scheme, system.dt, system.fields
        quad = self._quadrature
        us = [solution.state.u, *[s.u for s in system.history]]
        ubar = solution.mean[: ch.nu]
        R = ch.radius
        if axial is None:
            J_old = ch.geometry.stretch(1.0 + (ch.eta_at_quad @ eta_old).reshape(ch.quad_shape) / R)
            J_new = ch.geometry.stretch(1.0 + (ch.eta_at_quad @ eta_new).reshape(ch.quad_shape) / R)
        else:  # ``axial``: the lumen's d_z at tⁿ and tⁿ⁺¹
            J_old = volume_element(ch, deformation(ch, eta_old, self.extension.at_quad(axial[0])))
            J_new = volume_element(ch, deformation(ch, eta_new, self.extension.at_quad(axial[1])))

        def q(J):
            return lambda x: quad.kinetic(J, x)

        us = [quad.values(u) for u in us]  # the identity's quadratures are on values, linear in the DOFs
        stored_new = S.stored(q(J_new), us)
        stored_old = S.before(q(J_old), us)
        geometric = (S.stored(q(J_new - fields.J), us) - S.before(q(J_old - fields.J), us)
                     - dt * quad.kinetic(fields.dJdt, quad.values(ubar)))
        strain = quad.strain_squared(ubar, fields)
        # each end's outward flux Q̄ = ∫ J ū·n, and what its condition makes of the power −Δt p̄ Q̄ it hands the fluid
        fluxes = self.ends.fluxes(ubar, fields)
        tractions = self.ends.resolve(system.tractions, solution.mean)  # a flow-rate end's p̄ is its λ
        old_ends, new_ends = system.history[0].ends, solution.state.ends
        end_work, end_dissipation, end_power, end_columns = {}, {}, {}, {}
        for end, condition in self.ends.conditions.items():
            traction, flux = tractions[end], fluxes[end]
            work, dissipation = condition.ledger(end, traction, flux, dt, old_ends.get(end), new_ends.get(end))
            end_work.update(work)
            end_dissipation.update(dissipation)
            end_power[end] = -dt * traction.mean(flux) * flux
            end_columns.update({f"end.{end}.Q": flux, f"end.{end}.p": traction.mean(flux),
                                **condition.columns(end, new_ends.get(end))})
        advecting = S.extrapolate([s.u for s in system.history]) if self.advection else None
        convection = self.ends.convection_ledger(ubar, advecting, fields, dt)  # static-pressure ends only
        terms = {
            "kinetic.fluid": stored_new,
            "kinetic.fluid_before": stored_old,
            "dissipation.viscous.fluid": 2.0 * self.viscosity * dt * strain,
            "dissipation.numerical.fluid": S.numerical(q(fields.J), us),
            "dissipation.geometric.fluid": -geometric,
            **end_work,
            **end_dissipation,
            **convection,
            **self.ends.energy(new_ends),
            **end_columns,
        }
        if self.wall == "prescribed":
            A = self.pattern.matrix(system.data)
            terms["work.wall"] = dt * float(system.fixed_values @ (A @ solution.mean - system.rhs)[self.fixed])
        interface = 0.0
        if system.interface is not None:
            vbar = ch.wall_trace(ubar)
            interface = dt * float(vbar @ (system.interface.matrix @ vbar - system.interface.rhs))
        stabilization = 0.0  # SUPG's and grad-div's part of the step tested with ū, by quadrature of the fields
        if system.stabilized is not None:
            history = S.history([s.u for s in system.history])
            terms["dissipation.stabilization.fluid"] = system.stabilized.supg_power(
                ubar, solution.mean[ch.nu:ch.ndofs], history)
            terms["dissipation.grad_div.fluid"] = system.stabilized.grad_div_power(ubar)
            stabilization = terms["dissipation.stabilization.fluid"] + terms["dissipation.grad_div.fluid"]
        after = (stored_new + terms["dissipation.numerical.fluid"] + terms["dissipation.viscous.fluid"] + interface
                 + sum(convection.values()) + stabilization)
        before = stored_old + end_power["inlet"] + end_power["outlet"] + terms.get("work.wall", 0.0) + geometric
        terms["interface.power"] = interface
        terms["a2.residual"] = after - before
        terms["a2.scale"] = max(abs(after), abs(before), 1e-300)
        self.ledger_s += time.perf_counter() - t0
        return terms
