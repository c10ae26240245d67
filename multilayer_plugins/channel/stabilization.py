"""Residual-based stabilization of the Navier–Stokes step: SUPG on the momentum residual, and grad-div.

At a cell Péclet number |a| h / 2ν ≫ 1 (an artery's systole on a clinical
mesh: |a| ~ 100 cm/s, h ~ 0.1 cm, ν = 0.033 cm²/s gives ~150) the Galerkin
step's convection has no control of the streamwise gradients, and the
velocity oscillates from node to node.  SUPG is added to the step of
:mod:`multilayer_plugins.channel.step` (theory §5, "Stabilization of
convection"), with grad-div (γ = ``grad_div``, :data:`GRAD_DIV` by default):

    Σ_K ∫_K J τ_M ((a·∇^η) q) · R_M(ū, p̄)                   (SUPG)
  + Σ_K ∫_K J ρ_f τ_C (∇^η·ū)(∇^η·q)                        (grad-div)

with R_M the strong residual of the momentum equation at the step's test
level, the scheme's difference quotient included,

    R_M = ρ_f δ_t u + ρ_f (a·∇^η) ū − μ Δ^η ū + ∇^η p̄,   δ_t u = ((α₀/β₀) ū + h)/Δt,

δ_t u the time scheme's difference quotient as the step's mass term
carries it (h the scheme's old levels, on the right-hand side), a the
step's advecting velocity (the extrapolated u minus the domain velocity w,
as in the advection term), and ∇^η·ū the divergence with a tube's hoop
term u_r/r.  Both terms vanish on a solution of the equations (R_M = 0,
∇·u = 0): the stabilized step is consistent, and
Poiseuille flow, which P2 holds exactly, stays exact.

In a tube (radial power k = 1) the vector Laplacian has the cylindrical
terms: (Δu)_z = ∂_zz u_z + ∂_rr u_z + (k/r)∂_r u_z and
(Δu)_r = ∂_zz u_r + ∂_rr u_r + (k/r)∂_r u_r − k u_r/r².  The second
derivatives are those of the element (constant on a P2 triangle) mapped by
the ALE map's derivative at the point; the derivatives of the map's own
coefficients (terms in η_z² and η_zz that multiply first derivatives of u)
are left out, so the residual is exact on a uniformly dilated channel and
on a rigid one, and its error on a curved wall is O(|η_zz| r̂ + |η_z|²).

The parameters are those of the residual-based variational multiscale
method (Bazilevs et al. 2007), with the metric tensor G = 4 (∂ξ/∂x)ᵀ(∂ξ/∂x)
of the map from the unit reference triangle (so a·G a = (2|a|/h)² for a cell
of size h along a):

    τ_M = ((2ϱ)² + a·G a + C_I ν² G:G)^(−1/2),    τ_C = γ |a| h_a / 2,   h_a = 2|a| / (a·G a)^(1/2),

C_I = 36, ν = μ/ρ_f, ϱ = (α₀/β₀)/Δt the rate of the step's mass term (1/Δt
for backward Euler, 1.5/Δt for BDF2, 2/Δt for Crank–Nicolson), h_a the
cell's size along a, and γ the case file's ``grad_div`` (:data:`GRAD_DIV`
by default).  τ_M's (2ϱ)² keeps τ_M ϱ ≤ ½: SUPG's part of the mass
term, ρ_f τ_M ϱ ((a·∇)q)·ū, is not sign-definite (tested with ū it is a
flux through the ends), and with τ_M ~ h/2|a| > Δt (a coarse mesh, no time
term) the centreline velocity of the 10 × 2 tube of
tests/test_fluid_stabilization.py reached −287 times the mean velocity.  So
the stabilized step changes with Δt: refined in Δt at a fixed mesh it tends
to that mesh's Galerkin step.  With ``supg_dt`` = Δt_τ the rate in τ_M is
max(ϱ, 1/Δt_τ): every step at that rate or slower solves one stabilized
problem (an adaptive run's default, at its smallest step, so that its error
estimate sees all that changes with the step), and τ_M ϱ ≤ ½ still holds.  τ_C is the convective scaling of grad-div (a
cell viscosity |a|h/2 on the divergence): it vanishes with a, so at small
Reynolds numbers the stabilized step departs from the Galerkin one in
proportion to Re, as advection itself does, and it does not depend on Δt.
(The variational multiscale choice 1/(τ_M tr G) would do neither: at small
Δt it is ~h²/(4Δt), hundreds of times ν at an artery's Δt = 1e-3 s whatever
the flow, and it turned the couplers' second-order convergence in Δt on the
pulse cases into order ≤ 0.36.)  The default γ = 0.1 is where grad-div's
effect has saturated on the bundled carotid-like artery (theory §5: its
centreline velocity moves by tens of cm/s from γ = 0 to 0.1, by a few from
0.1 to 1, and at 0.1 its 30 × 4 mesh agrees with the 60 × 8 one) while a
resolved answer hardly moves (the quick start's peaks by ≤ 0.07 %, by
0.32 % at γ = 1).  Both parameters are evaluated at every
quadrature point with the step's a, so the step stays linear.

The matrices are assembled here from the element jets (values, physical
gradients, Laplacians of the local basis functions, chunk by chunk of
elements); the energy identity's terms (:meth:`Stabilized.supg_power`,
:meth:`Stabilized.grad_div_power`) by quadrature of the solved fields,
never from these matrices.
"""

from __future__ import annotations

import attrs
import numpy as np

from multilayer.numerics.assembly.batched import CHUNK, affine_inverse
from multilayer_plugins.channel.ale import ALEFields
from multilayer_plugins.channel.channel import Channel

#: The kinds of ``[fluid] stabilization``.
KINDS = ("supg", "none")

#: γ of grad-div by default (see the module's docstring for why this value)
GRAD_DIV = 0.1

#: C_I of τ_M's viscous part (the inverse estimate's constant; Bazilevs et al. 2007 use 36 for linear elements)
C_INVERSE = 36.0

#: The step of the central difference that gives the reference Hessians: exact for the cubic (bubble) functions
#: of P1b and the quadratics of P2, since their gradients are at most quadratic.
_DIFFERENCE = 0.25


def _reference_jets(element, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(values (s, q), gradients (s, i, q), Hessians (s, i, j, q)) of a scalar element's local functions at X."""
    n = element.doflocs.shape[0]
    values, grads, hessians = [], [], []
    for s in range(n):
        phi, dphi = element.lbasis(X, s)
        hess = np.empty((2, 2, X.shape[1]))
        for j in range(2):
            step = np.zeros((2, 1))
            step[j] = _DIFFERENCE
            ahead, behind = element.lbasis(X + step, s)[1], element.lbasis(X - step, s)[1]
            hess[:, j] = (ahead - behind) / (2.0 * _DIFFERENCE)
        values.append(phi)
        grads.append(dphi)
        hessians.append(0.5 * (hess + hess.transpose(1, 0, 2)))
    return np.array(values), np.array(grads), np.array(hessians)


def _map_rows(fields: ALEFields, cut: slice) -> tuple:
    """P[d][k] at the points of ``cut``: ∂_d = Σ_k P[d][k] ∂_x̂k (d, k ∈ (z, r)), the ALE map's derivative."""
    gz, gr = fields.gz[cut], fields.gr[cut]
    if fields.gzz is None:
        return ((1.0, gz), (0.0, gr))
    return ((fields.gzz[cut], gz), (fields.grz[cut], gr))


class Stabilization:
    """The element jets the stabilization terms need, built once for a channel.

    Parameters
    ----------
    channel : Channel
        Its velocity basis (P2 or P1b, vector) and pressure basis (P1) on one affine mesh and quadrature.
    density, viscosity : float
        ρ_f and μ.
    grad_div : float
        γ ≥ 0, the scale of τ_C.
    supg_dt : float, optional
        Δt_τ > 0: τ_M's rate is max(ϱ, 1/Δt_τ) (None: ϱ, the step's own).
    """

    def __init__(self, channel: Channel, density: float, viscosity: float, grad_div: float = 0.0,
                 supg_dt: float | None = None):
        if not grad_div >= 0.0:
            raise ValueError(f"grad_div must be ≥ 0, got {grad_div!r}")
        if supg_dt is not None and not supg_dt > 0.0:
            raise ValueError(f"supg_dt must be > 0, got {supg_dt!r}")
        self.channel, self.density, self.viscosity, self.grad_div = channel, density, viscosity, float(grad_div)
        #: the least rate τ_M sees (1/s): 0 by default, 1/Δt_τ with ``supg_dt``
        self.rate_floor = 0.0 if supg_dt is None else 1.0 / supg_dt
        vb, pb = channel.velocity, channel.pressure
        self.hoops = channel.geometry.radial_power
        self.inverse = affine_inverse(vb)  # (i, k, e): ∂_x̂k = Σ_i inverse[i, k] ∂̂_i
        X = vb.X
        self.values, self.grads, self.hessians = _reference_jets(vb.elem.elem, X)
        _, self.pressure_grads, _ = _reference_jets(pb.elem, X)
        self.dofs = vb.element_dofs  # (2 s + c, e): local function i is component i % 2 of scalar function i // 2
        self.pressure_dofs = pb.element_dofs
        self.dx = vb.dx
        self.ns = self.values.shape[0]
        self.nelems = vb.nelems
        self._jets: tuple = (None, {})  # (the domain's fields, their jets per chunk): see jets

    def chunks(self):
        for e0 in range(0, self.nelems, CHUNK):
            yield slice(e0, min(e0 + CHUNK, self.nelems))

    # -- jets on a chunk --------------------------------------------------------
    def _inverse_map(self, P: tuple, cut: slice) -> np.ndarray:
        """Ξ (i, d, e, q) = ∂ξ_i/∂x_d: the reference cell's coordinates' derivatives in the physical domain."""
        inv = self.inverse[:, :, cut, None]  # (i, k, e, 1)
        shape = (len(range(*cut.indices(self.nelems))), self.dx.shape[1])
        return np.array([[np.broadcast_to(P[d][0] * inv[i, 0] + P[d][1] * inv[i, 1], shape) for d in range(2)]
                         for i in range(2)])

    def jets(self, fields: ALEFields, cut: slice) -> tuple:
        """(Ξ, gradients (d, s, e, q), Laplacians (s, e, q), pressure gradients (d, p, e, q), 1/r or None) of the
        local basis functions on the domain of ``fields``, kept for the last domain (a rigid wall's is the run's).

        Δ = Σ_ij ∂̂_i∂̂_j (Ξ Ξᵀ)_ij with the tube's (k/r)∂_r added; the derivatives of Ξ itself (the map's
        curvature) are left out (module docstring).
        """
        key = cut.start
        if self._jets[0] is not fields:
            self._jets = (fields, {})
        kept = self._jets[1].get(key)
        if kept is None:
            xi = self._inverse_map(_map_rows(fields, cut), cut)
            grad = np.einsum("siq,ideq->dseq", self.grads, xi)
            lap = np.einsum("sijq,ijeq->seq", self.hessians, np.einsum("ideq,jdeq->ijeq", xi, xi))
            hoop = None if fields.hoop is None else fields.hoop[cut]
            if self.hoops:
                lap += self.hoops * hoop * grad[1]
            pgrad = np.einsum("piq,ideq->dpeq", self.pressure_grads, xi)
            kept = self._jets[1][key] = (xi, grad, lap, pgrad, hoop)
        return kept

    def parameters(self, fields: ALEFields, a: np.ndarray, rate: float) -> tuple[np.ndarray, np.ndarray]:
        """(τ_M, τ_C) at the quadrature points (elements, points) for the advecting velocity ``a`` (2, e, q): τ_M in
        s, τ_C in cm²/s (grad-div's coefficient is ρ_f τ_C)."""
        nu = self.viscosity / self.density
        tau_m, tau_c = np.empty(self.dx.shape), np.empty(self.dx.shape)
        for cut in self.chunks():
            xi = self.jets(fields, cut)[0]
            G = 4.0 * np.einsum("ideq,ifeq->dfeq", xi, xi)  # G = 4 Ξᵀ Ξ
            ac = a[:, cut]
            aGa = sum(ac[d] * G[d, e] * ac[e] for d in range(2) for e in range(2))
            GG = sum(G[d, e] ** 2 for d in range(2) for e in range(2))
            tau_m[cut] = ((2.0 * rate) ** 2 + aGa + C_INVERSE * nu**2 * GG) ** -0.5
            speed2 = ac[0] ** 2 + ac[1] ** 2
            # τ_C = γ |a|²/√(a·Ga) = γ|a|h_a/2, and 0 where a = 0 (then a·Ga = 0 too)
            tau_c[cut] = self.grad_div * np.divide(speed2, np.sqrt(aGa), out=np.zeros_like(aGa), where=aGa > 0.0)
        return tau_m, tau_c

    def step(self, fields: ALEFields, a: np.ndarray, mass_coefficient: float, dt: float) -> Stabilized:
        """The terms of one step: the advecting velocity ``a`` (2, e, q), the step's mass coefficient (α₀/β₀) ρ_f/Δt."""
        tau_m, tau_c = self.parameters(fields, a, max(mass_coefficient / self.density, self.rate_floor))
        return Stabilized(self, fields, a, mass_coefficient, dt, tau_m, tau_c)


@attrs.frozen(eq=False)
class Stabilized:
    """The stabilization of one step: its element matrices, its right-hand side and its energy terms."""

    base: Stabilization
    fields: ALEFields
    a: np.ndarray
    mass_coefficient: float
    dt: float
    tau_m: np.ndarray
    tau_c: np.ndarray
    #: what :meth:`_chunk` made, per chunk: the matrices, the right-hand side and the ledger share it
    _made: dict = attrs.field(factory=dict, init=False)

    def _chunk(self, cut: slice):
        """(weighted test jets (a·∇s) τ_M J dx, the momentum operator on z and r components, divergence jets,
        pressure gradients) of the local basis functions on ``cut``."""
        if cut.start not in self._made:
            self._made[cut.start] = self._make(cut)
        return self._made[cut.start]

    def _make(self, cut: slice):
        b, f = self.base, self.fields
        _, grad, lap, pgrad, hoop = b.jets(f, cut)
        a = self.a[:, cut]
        values = b.values[:, None, :]  # (s, 1, q)
        transport = a[0] * grad[0] + a[1] * grad[1]
        J, dx = f.J[cut], b.dx[cut]
        test = transport * (self.tau_m[cut] * J * dx)
        operator_z = self.mass_coefficient * values + b.density * transport - b.viscosity * lap
        operator_r = operator_z
        if b.hoops:
            operator_r = operator_z + (b.viscosity * b.hoops) * hoop**2 * values
        div_z, div_r = grad[0], grad[1]
        if b.hoops:
            div_r = div_r + b.hoops * hoop * values
        return test, (operator_z, operator_r), (div_z, div_r), pgrad

    def velocity_block(self, shape: tuple) -> np.ndarray:
        """Element matrices (test i, trial j, element) of SUPG's velocity terms and grad-div, in the layout of
        the step's velocity block (:class:`~multilayer.numerics.assembly.batched.BatchedForm` of the velocity)."""
        b = self.base
        out = np.zeros(shape)
        weight = b.density * self.tau_c * self.fields.J * b.dx
        for cut in b.chunks():
            test, operators, divs, _ = self._chunk(cut)
            for c in range(2):
                out[c::2, c::2, cut] += np.einsum("seq,teq->ste", test, operators[c])
            for c in range(2):
                for d in range(2):
                    out[c::2, d::2, cut] += np.einsum("seq,teq->ste", divs[c] * weight[cut], divs[d])
        return out

    def pressure_block(self, npressure: int) -> np.ndarray:
        """SUPG's ∫ J τ_M ((a·∇)q)·∇p̄ as element matrices (pressure trial j, velocity test i, element): the
        layout of the step's divergence block, whose transpose it is added to."""
        b = self.base
        out = np.empty((npressure, 2 * b.ns, b.nelems))
        for cut in b.chunks():
            test, _, _, pgrad = self._chunk(cut)
            for c in range(2):
                out[:, c::2, cut] = np.einsum("seq,peq->pse", test, pgrad[c])
        return out

    def rhs(self, history: np.ndarray) -> np.ndarray:
        """−(ρ_f/Δt) ∫ J τ_M ((a·∇)q)·h for the scheme's history h (a velocity DOF vector): the residual's
        old levels, on the right-hand side."""
        b = self.base
        local = np.zeros(b.dofs.shape)
        for cut in b.chunks():
            test, _, _, _ = self._chunk(cut)
            h = history[b.dofs[:, cut]]  # (i, e)
            for c in range(2):
                values = np.einsum("se,sq->eq", h[c::2], b.values)
                local[c::2, cut] = -(b.density / self.dt) * np.einsum("seq,eq->se", test, values)
        return np.bincount(b.dofs.ravel(), weights=local.ravel(), minlength=b.channel.velocity.N)

    # -- the energy identity -----------------------------------------------------
    def _fields(self, u: np.ndarray, p: np.ndarray, cut: slice):
        """u's (values, physical gradients, Laplacians) per component and p's gradient on ``cut``, from the DOFs."""
        b = self.base
        _, grad, lap, pgrad, hoop = b.jets(self.fields, cut)
        ue = u[b.dofs[:, cut]]
        comps = []
        for c in range(2):
            coef = ue[c::2]  # (s, e)
            comps.append((np.einsum("se,sq->eq", coef, b.values), np.einsum("se,dseq->deq", coef, grad),
                          np.einsum("se,seq->eq", coef, lap)))
        pe = p[b.pressure_dofs[:, cut]]
        return comps, np.einsum("pe,dpeq->deq", pe, pgrad), hoop

    def supg_power(self, ubar: np.ndarray, pbar: np.ndarray, history: np.ndarray) -> float:
        """Δt ∫ J τ_M ((a·∇)ū)·R_M(ū, p̄): what the SUPG term takes from the step tested with ū."""
        b, f = self.base, self.fields
        total = 0.0
        for cut in b.chunks():
            comps, pgrad, hoop = self._fields(ubar, pbar, cut)
            old, _, _ = self._fields(history, np.zeros(b.channel.pressure.N), cut)
            a = self.a[:, cut]
            for c in range(2):
                value, grad, lap = comps[c]
                transport = a[0] * grad[0] + a[1] * grad[1]
                viscous = lap - (b.hoops * hoop**2 * value if (b.hoops and c == 1) else 0.0)
                residual = (self.mass_coefficient * value + (b.density / self.dt) * old[c][0]
                            + b.density * transport - b.viscosity * viscous + pgrad[c])
                total += float(np.sum(b.dx[cut] * f.J[cut] * self.tau_m[cut] * transport * residual))
        return self.dt * total

    def grad_div_power(self, ubar: np.ndarray) -> float:
        """Δt ∫ J ρ_f τ_C (∇·ū)² ≥ 0: grad-div's dissipation over the step."""
        b, f = self.base, self.fields
        total = 0.0
        for cut in b.chunks():
            comps, _, hoop = self._fields(ubar, np.zeros(b.channel.pressure.N), cut)
            div = comps[0][1][0] + comps[1][1][1]
            if b.hoops:
                div = div + b.hoops * hoop * comps[1][0]
            total += float(np.sum(b.dx[cut] * f.J[cut] * b.density * self.tau_c[cut] * div**2))
        return self.dt * total
