"""One fluid step, SCHEME §3 A2: the linear Oseen-type problem for (u, p, v).

On the reference channel, with the ALE fields of ηⁿ and the wall velocity
v^{n+½} of the structure step, find (u, p) with u_r = 0 on the axis, inlet
and outlet, u_z = 0 on the wall, and u_r = v on the wall, such that

    ρ_f/Δt mass_J(u − uⁿ, q) + ρ_f advection_skew(u, q) + ρ_f moving_domain(u, q)
  + 2μ viscous(u, q) − ∫ J p ∇^η·q + ∫ J π ∇^η·u + (1/Δt) (v − v^{n+½})ᵀ M ψ
  = P_in ∫_Γin J q_z − P_out ∫_Γout J q_z.

Wall modes:

``coupled``
    the wall's u_r DOFs are free: they are the line unknowns v, carrying
    the thin layer's inertia through the Robin mass M = ρ₁h∫vψ;
``rigid``
    u = 0 on the wall, ηⁿ = 0, v = 0;
``prescribed``
    u_r = v^{n+½} on the wall (Dirichlet), with v^{n+½} = (η^{n+1} − ηⁿ)/Δt
    the velocity of a wall moved by a given law.

The matrix is assembled into a sparsity pattern fixed at setup
(:class:`multilayer.assembly.pattern.Pattern`).  In the rigid mode only the
advection term changes between steps (the rest is assembled once), and a
Stokes fluid on a rigid wall has a constant matrix: it is factorized once.
"""

from __future__ import annotations

import time

import attrs
import numpy as np
import scipy.sparse as sp

from multilayer_plugins.channel import forms
from multilayer_plugins.channel.ale import ALEFields
from multilayer.assembly.batched import BatchedForm
from multilayer_plugins.channel.channel import Channel
from multilayer_plugins.channel.ledger import a2_terms
from multilayer.assembly.pattern import Pattern
from multilayer.linsolve import Factorized, SolverStats, factorize
from multilayer.spaces import prolongation_dofs

WALL_MODES = ("coupled", "rigid", "prescribed")


@attrs.frozen(eq=False)
class FluidState:
    """Velocity and pressure DOFs on the reference channel, and the wall velocity.

    ``v`` is the wall's u_r as a vector of the interface line's space:
    the kinematic condition u = v e_r on Γ, in the thin layer's numbering.
    """

    u: np.ndarray
    p: np.ndarray
    v: np.ndarray


@attrs.frozen(eq=False)
class StepResult:
    """The new state, the terms of the A2 energy identity, and the seconds per phase."""

    state: FluidState
    energy: dict[str, float]
    timings: dict[str, float]


class FluidStep:
    """The A2 step of one fluid on one channel, for a fixed Δt and wall mode.

    Parameters
    ----------
    channel : Channel
        Reference mesh, spaces and DOF sets.
    density, viscosity : float
        ρ_f (g/cm³) and μ (poise).
    advection : bool
        True for Navier–Stokes, False for Stokes (the moving-domain term stays).
    dt : float
        Δt (s).
    wall : str
        ``"coupled"``, ``"rigid"`` or ``"prescribed"``.
    solver : str
        A backend of :mod:`multilayer.linsolve`.
    """

    def __init__(
        self,
        channel: Channel,
        density: float,
        viscosity: float,
        advection: bool,
        dt: float,
        wall: str = "coupled",
        solver: str = "superlu",
    ):
        if wall not in WALL_MODES:
            raise ValueError(f"wall mode {wall!r} is not one of {WALL_MODES}")
        if not dt > 0.0:
            raise ValueError(f"time step must be > 0 s, got {dt!r}")
        self.channel = channel
        self.density = density
        self.viscosity = viscosity
        self.advection = advection
        self.dt = dt
        self.wall = wall
        self.solver = solver
        self.stats = SolverStats()
        self.assembly_s = 0.0
        self.ledger_s = 0.0

        ub, pb = channel.velocity, channel.pressure
        nu, n = channel.nu, channel.ndofs
        self._uu = BatchedForm(ub)
        self._pu = BatchedForm(ub, pb)
        uu, pu = (self._uu.rows, self._uu.cols), (self._pu.rows + nu, self._pu.cols)
        self.pattern = Pattern((n, n), [uu, pu, pu[::-1]])
        self._slots_uu = self.pattern.slots(*uu)
        self._slots_pu = self.pattern.slots(*pu)
        self._slots_up = self.pattern.slots(*pu[::-1])
        self._wall_dof = prolongation_dofs(channel.prolongation)  # velocity DOF of each line DOF

        fixed = [channel.normal_r, channel.wall_z]
        if wall != "coupled":
            fixed.append(channel.wall_r)
        self.fixed = np.unique(np.concatenate(fixed))
        self.free = np.setdiff1d(np.arange(n), self.fixed)
        self._block_ff = self.pattern.block(self.free, self.free)
        self._block_fd = self.pattern.block(self.free, self.fixed)

        self._load_in = forms.dynamic_pressure.assemble(channel.inlet, J=1.0)
        self._load_out = forms.dynamic_pressure.assemble(channel.outlet, J=1.0)
        self._rigid = ALEFields.rigid(channel)
        self._constant: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._data: np.ndarray | None = None
        self._factorized: Factorized | None = None
        self._robin_cache: tuple | None = None

    # -- assembly -------------------------------------------------------------

    def _kernels(self, fields: ALEFields, u_old: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Kernels of the velocity block (all terms summed), of mass_J, and of the divergence."""
        if self._constant is not None:
            K_static, K_mass, K_div = self._constant
        else:
            kw = fields.forms_kwargs()
            K_mass = self._uu.kernel(forms.mass_J, **kw)
            K_static = (self.density / self.dt) * K_mass + (2.0 * self.viscosity) * self._uu.kernel(forms.viscous, **kw)
            K_div = self._pu.kernel(forms.pressure_divergence, **kw)
            if self.wall == "rigid":
                self._constant = (K_static, K_mass, K_div)
        K = K_static
        if np.any(fields.dJdt):
            K = K + self.density * self._uu.kernel(forms.moving_domain, dJdt=fields.dJdt)
        if self.advection:
            a = np.array(self.channel.velocity.interpolate(u_old))
            a[1] -= fields.wr
            K = K + self.density * self._uu.kernel(forms.advection_skew, a=a, **fields.forms_kwargs())
        return K, K_mass, K_div

    def _robin(self, robin_mass: sp.spmatrix | None) -> list[tuple[np.ndarray, np.ndarray]]:
        """(slots, values) of (1/Δt) P M Pᵀ, the thin layer's inertia on the wall u_r DOFs.

        A coupler hands the same matrix every step: its slots are looked up once.
        """
        if robin_mass is None:
            return []
        if self._robin_cache is None or self._robin_cache[0] is not robin_mass:
            M = sp.coo_matrix(robin_mass)
            rows, cols = self._wall_dof[M.row], self._wall_dof[M.col]
            self._robin_cache = (robin_mass, self.pattern.slots(rows, cols), M.data / self.dt)
        return [self._robin_cache[1:]]

    def assemble(
        self,
        fields: ALEFields,
        u_old: np.ndarray,
        v_half: np.ndarray,
        p_in: float,
        p_out: float,
        robin_mass: sp.spmatrix | None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The CSR data of the full A2 matrix (in :attr:`pattern`) and its right-hand side."""
        ch = self.channel
        if self.constant_matrix and self._data is not None:
            data = self._data
            K_mass = self._constant[1]
        else:
            K, K_mass, K_div = self._kernels(fields, u_old)
            div = self._pu.matrix_data(K_div)
            data = self.pattern.fill(
                [(self._slots_uu, self._uu.matrix_data(K)), (self._slots_pu, div), (self._slots_up, -div)]
                + self._robin(robin_mass)
            )
            if self.constant_matrix:
                self._data = data
        b = np.zeros(ch.ndofs)
        b[: ch.nu] = (self.density / self.dt) * self._uu.apply(K_mass, u_old)
        b[: ch.nu] += p_in * fields.J_in * self._load_in + p_out * fields.J_out * self._load_out
        if robin_mass is not None:
            b[: ch.nu] += ch.prolongation @ (robin_mass @ v_half) / self.dt
        return data, b

    # -- the step -------------------------------------------------------------

    def _wall_data(
        self, eta: np.ndarray | None, v_half: np.ndarray | None, robin_mass: sp.spmatrix | None
    ) -> tuple[np.ndarray, np.ndarray]:
        nline = self.channel.line.ndofs
        eta = np.zeros(nline) if eta is None else np.asarray(eta, dtype=float)
        v_half = np.zeros(nline) if v_half is None else np.asarray(v_half, dtype=float)
        if eta.shape != (nline,) or v_half.shape != (nline,):
            raise ValueError(f"η and v must be vectors of the interface line ({nline} DOFs)")
        if self.wall == "rigid" and (np.any(eta) or np.any(v_half)):
            raise ValueError("a rigid wall does not move: pass η = v = 0 (or None)")
        if self.wall != "coupled" and robin_mass is not None:
            raise ValueError(f"a Robin mass only enters the coupled wall mode, not {self.wall!r}")
        if robin_mass is not None and robin_mass.shape != (nline, nline):
            raise ValueError(f"the Robin mass must be a {nline} × {nline} matrix on the interface line")
        if self.wall == "prescribed":
            ends = list(self.channel.ends)
            scale = max(np.max(np.abs(v_half)), 1e-300)
            if np.max(np.abs(v_half[ends])) > 1e-12 * scale:
                raise ValueError("a prescribed wall motion must vanish at z = 0 and z = L (u_r = 0 there)")
        return eta, v_half

    def step(
        self,
        state: FluidState,
        eta: np.ndarray | None = None,
        v_half: np.ndarray | None = None,
        p_in: float = 0.0,
        p_out: float = 0.0,
        robin_mass: sp.spmatrix | None = None,
    ) -> StepResult:
        """Advance (u, p, v) over one Δt on the domain of ``eta`` (= ηⁿ).

        ``v_half`` is v^{n+½} (cm/s): the domain velocity, and in the
        prescribed mode the wall's u_r.  ``p_in``/``p_out`` are the time
        averages of the dynamic pressures over the step (dyn/cm²).
        ``robin_mass`` is M = ρ₁h∫vψ on the line (coupled mode only).
        """
        ch = self.channel
        eta, v_half = self._wall_data(eta, v_half, robin_mass)
        t0 = time.perf_counter()
        fields = self._rigid if self.wall == "rigid" else ALEFields.at(ch, eta, v_half)
        data, b = self.assemble(fields, state.u, v_half, p_in, p_out, robin_mass)

        x = np.zeros(ch.ndofs)
        if self.wall == "prescribed":
            x[: ch.nu] = ch.prolongation @ v_half
            x[ch.normal_r] = 0.0
        fixed_values = x[self.fixed]
        rhs = b[self.free] - self._block_fd.matrix(data) @ fixed_values
        assembly_s = time.perf_counter() - t0
        self.assembly_s += assembly_s

        before = (self.stats.factorization_s, self.stats.solve_s)
        lu = self._factorized
        if lu is None or not self.constant_matrix:
            lu = factorize(self._block_ff.matrix(data), self.stats, self.solver)
            self._factorized = lu if self.constant_matrix else None
        x[self.free] = lu.solve(rhs)

        t1 = time.perf_counter()
        u, p = x[: ch.nu], x[ch.nu :]
        v = ch.wall_trace(u)
        wall_work = 0.0  # the reaction's power: nonzero only where u_r is prescribed
        if self.wall == "prescribed":
            A = self.pattern.matrix(data)
            wall_work = self.dt * float(fixed_values @ (A @ x - b)[self.fixed])
        energy = a2_terms(
            ch, self.density, self.viscosity, self.dt, fields, state.u, u, v_half, v,
            p_in, p_out, robin_mass, wall_work,
        )
        ledger_s = time.perf_counter() - t1
        self.ledger_s += ledger_s
        timings = {
            "assembly": assembly_s,
            "factorization": self.stats.factorization_s - before[0],
            "solve": self.stats.solve_s - before[1],
            "ledger": ledger_s,
        }
        return StepResult(FluidState(u.copy(), p.copy(), v), energy, timings)

    @property
    def constant_matrix(self) -> bool:
        """True when the A2 matrix never changes: Stokes on a rigid wall, fixed Δt."""
        return self.wall == "rigid" and not self.advection
