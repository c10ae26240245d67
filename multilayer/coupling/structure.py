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

A wall with a nonlinear layer (:class:`~multilayer.wall.layer.NonlinearForms`)
solves the same step for its forces, F̄ − Σ_i [M_i(α₀/β₀ V̄ + h_i)/Δt + g_i(V̄) + f̂_i] = 0
(:meth:`StructureStep.residual`), by Newton's method (:mod:`multilayer.numerics.newton`)
with the tangent (α₀/β₀) M/Δt + C_T + (β₀Δt/α₀) K_T (:meth:`StructureStep.tangent`),
each correction solved by a :class:`~multilayer.numerics.linsolve.ReusingSolver`.
f̂_i is the internal force the scheme's energy identity needs (:func:`step_force`).
A linear wall takes the same loop's one correction: the back-substitution above.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence

import attrs
import numpy as np
import scipy.sparse as sp

from multilayer.numerics.linsolve import (
    LowRank,
    Reuse,
    ReusingSolver,
    SolverStats,
    factorize,
)
from multilayer.numerics.newton import NewtonResult, newton
from multilayer.numerics.timescheme import TimeScheme
from multilayer.scene.state import State, WallState
from multilayer.wall.layer import LayerMatrices
from multilayer.wall.stack import Stack

#: |W(d¹) − W(d⁰) − ∇W(d_mid)·Δd| below this share of the energies is round-off: no discrete-gradient correction
GRADIENT_ROUND_OFF = 1e-13


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
    #: how the step's Newton solve went (None when V̄ was solved elsewhere: a monolithic system)
    newton: NewtonResult | None = None


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
    reuse : Reuse
        How a nonlinear wall's Newton corrections reuse factorizations (``[solver] reuse``).
    chord : float or None
        A nonlinear wall's Newton iteration holds its tangent while each correction lowers the residual by this
        factor (:func:`~multilayer.numerics.newton.newton`'s ``chord``); None: Newton's own, a tangent each
        correction.
    """

    def __init__(self, stack: Stack, scheme: TimeScheme, dt: float, stats: SolverStats,
                 backend: str = "superlu", fluid_line: int | None = None, reuse: Reuse = Reuse(),
                 chord: float | None = None):
        self.stack = stack
        self.scheme = scheme
        self.dt = dt
        self.fluid_line = fluid_line
        self.chord = chord
        self._stats, self._backend, self._reuse = stats, backend, reuse
        # what the steps of every scheme :meth:`using` this one share: the factors of the last matrix and its key
        # (factorized at the first step: a monolithic solve uses only matrix() and rhs()), a nonlinear wall's
        # solver (made at its first step)
        self._shared: dict = {"key": None, "factors": None, "newton": None}

    def using(self, scheme: TimeScheme) -> StructureStep:
        """This wall step with ``scheme`` (a stage's), its factors shared: a step whose matrix has the same
        coefficients (:meth:`matrix_key`) is not factorized again, as TR-BDF2's two stages."""
        other = copy.copy(self)
        other.scheme = scheme
        return other

    def matrix_key(self, dt: float) -> tuple[float, float]:
        """The coefficients of M and K in :meth:`matrix` for Δt = ``dt``, (α₀/β₀)/Δt and β₀Δt/α₀, to 12 digits
        (C's is 1): two steps with the same key have the same matrix, to round-off."""
        s = self.scheme
        return float(f"{s.inertia / dt:.12g}"), float(f"{s.displacement_gain(dt):.12g}")

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
        (energy at the end of the step, work, dissipation).  A linear wall's
        step is one back-substitution with the factors of :meth:`matrix`
        (a Δt other than the last step's changes the matrix: it is factorized
        again); a nonlinear wall's, Newton's iteration from V̄ = 0.
        """
        st, dt = self.stack, self.dt if dt is None else dt
        states = state.history(self.scheme.levels - 1)
        free = st.free
        if st.linear:
            result = newton(None, lambda x, r: self._factors(dt).solve(r), None, linear=True,
                            first=self.rhs(states, forces, dt)[free])
        else:
            def residual(x):
                r, size = self.residual(states, forces, self._full(x), dt)
                return r[free], size[free]

            held: list = []  # the tangent on the free DOFs, the iterate it is at and its low-rank part

            def solve(x, r):
                if not (held and np.array_equal(held[0][0], x)):
                    J, update = self.jacobian(states, self._full(x), dt)
                    if update is not None:
                        update = LowRank(update.U[free], update.W[free])
                    held[:] = [(x.copy(), J[free][:, free], update)]
                tangent = held[0]  # (it stands for its matrix: a held one is factorized at its second solve)
                return self._nonlinear_solver().solve(tangent[1], r, key=tangent, update=tangent[2],
                                                      lasting=self.chord is not None)

            result = newton(residual, solve, np.zeros(free.size), stats=self._stats, chord=self.chord)
        return self.finish(states, self._full(result.x), forces, dt, result)

    def _full(self, x: np.ndarray) -> np.ndarray:
        """The wall vector of the free DOFs' values ``x`` (zero on the essential DOFs)."""
        mean = np.zeros(self.stack.space.ndofs)
        mean[self.stack.free] = x
        return mean

    def _nonlinear_solver(self) -> ReusingSolver:
        if self._shared["newton"] is None:
            self._shared["newton"] = ReusingSolver(self._stats, self._backend, self._reuse)
        return self._shared["newton"]

    def _layer_dofs(self, index: int, forms: LayerMatrices) -> np.ndarray:
        """The DOFs layer ``index``'s matrices touch (:func:`layer_dofs`), found once."""
        masks = self._shared.setdefault("dofs", {})
        if index not in masks:
            masks[index] = layer_dofs(forms)
        return masks[index]

    def _gradient(self, index: int, forms: LayerMatrices, ds: Sequence[np.ndarray]) -> DiscreteGradient:
        """Layer ``index``'s :func:`discrete_gradient` from dⁿ = ds[1] to d^{n+1} = ds[0]; the last one kept, so that
        a Newton correction's residual and tangent at one V̄ evaluate it once, and W(dⁿ) kept for the step."""
        d1, d0 = ds[0], ds[1]
        cache = self._shared.setdefault("gradients", {})
        last = cache.get(index)
        if last is not None and np.array_equal(last[0], d1) and np.array_equal(last[1], d0):
            return last[2]
        before = last[2].before if last is not None and np.array_equal(last[1], d0) else None
        gradient = discrete_gradient(forms, d1, d0, self._layer_dofs(index, forms), before)
        cache[index] = (d1.copy(), d0.copy(), gradient)
        return gradient

    # -- the nonlinear step: its residual and tangent ----------------------------------
    def levels(self, states: Sequence[State], mean: np.ndarray, dt: float) -> list[np.ndarray]:
        """[d^{n+1}, dⁿ, ...]: the displacements of the step whose test-level velocity is V̄ = ``mean``."""
        old = [x.wall.d for x in states]
        return [self.scheme.displacement(mean, old, dt), *old]

    def residual(self, states: Sequence[State], forces: Mapping[str, np.ndarray], mean: np.ndarray,
                 dt: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The wall's out-of-balance force at V̄ = ``mean``, F̄ − Σ_i [M_i(α₀/β₀ V̄ + h_i)/Δt + g_i(V̄) + f̂_i],
        and entry by entry the sum of its terms' magnitudes (wall numbering, every DOF).

        Zero at the step's solution; for a linear wall it is :meth:`rhs` − :meth:`matrix` V̄.
        """
        st, s, dt = self.stack, self.scheme, self.dt if dt is None else dt
        loads = sum(forces.values(), np.zeros(st.space.ndofs))
        ds = self.levels(states, mean, dt)
        r, size = loads.copy(), np.abs(loads)
        for i, m in enumerate(st.matrices):
            h = s.history([self.own_velocity(i, x) for x in states])
            force = self._gradient(i, m, ds).force if not m.linear and midpoint(s) else step_force(s, m, ds)
            # a nonlinear layer's force may sum large elements' forces that cancel (a prestressed band): its size
            # is theirs (NonlinearForms.term_size)
            force_size = np.abs(force) if m.linear else m.term_size(force, s.average(ds))
            for term, magnitude in ((m.mass @ (s.inertia * mean + h) / dt, None), (m.damping_force(mean), None),
                                    (force, force_size)):
                r -= term
                size += np.abs(term) if magnitude is None else magnitude
        return r, size

    def tangent(self, states: Sequence[State], mean: np.ndarray, dt: float | None = None) -> sp.csr_matrix:
        """The sparse part of −∂(:meth:`residual`)/∂V̄ at V̄ = ``mean`` (:meth:`jacobian`'s first)."""
        return self.jacobian(states, mean, dt)[0]

    def jacobian(self, states: Sequence[State], mean: np.ndarray,
                 dt: float | None = None) -> tuple[sp.csr_matrix, LowRank | None]:
        """−∂(:meth:`residual`)/∂V̄ at V̄ = ``mean``, exactly: a sparse matrix and a low-rank term (None when there
        is none), both in wall numbering.

        The sparse part is (α₀/β₀) M/Δt + Σ_i C_T,i(V̄) + (β₀Δt/α₀) Σ_i K_T,i(d̄): all of it where the scheme's
        force is the force at d̄ (backward Euler, BDF2).  Crank–Nicolson's discrete gradient adds the
        derivative of its correction (:func:`gradient_derivative`): a diagonal on the layer's DOFs, kept in the
        sparse part, and a rank-one term per nonlinear layer, dense, which the solver adds by Woodbury's
        formula (:class:`~multilayer.numerics.linsolve.LowRank`) — so that Newton's iteration stays quadratic.
        """
        st, s, dt = self.stack, self.scheme, self.dt if dt is None else dt
        ds = self.levels(states, mean, dt)
        dbar = s.average(ds)
        gain = s.displacement_gain(dt)
        J = self._constant_part(dt)
        columns, rows = [], []
        diagonal = None
        for i, m in enumerate(st.matrices):
            if m.linear:
                continue
            K = m.tangent(dbar)
            C = m.damping_tangent(mean)
            J = J + K * gain if C.nnz == 0 else J + C + K * gain
            if midpoint(s):
                gradient = self._gradient(i, m, ds)
                if gradient.coefficient:
                    # d^{n+1} = (Δt V̄ − Σ_{k≥1} α_k d^{n+1−k})/α₀: its derivative in V̄ is Δt/α₀
                    diag, (u, w) = gradient_derivative(m, gradient, K, ds[0], self._layer_dofs(i, m))
                    diagonal = diag if diagonal is None else diagonal + diag
                    columns.append(u * (dt / s.alpha[0]))
                    rows.append(w)
        if diagonal is not None:
            J = J + sp.diags(diagonal * (dt / s.alpha[0]))
        update = LowRank(np.stack(columns, axis=1), np.stack(rows, axis=1)) if columns else None
        return sp.csr_matrix(J), update

    def _constant_part(self, dt: float) -> sp.csr_matrix:
        """(α₀/β₀) M/Δt + Σ_linear (C_i + (β₀Δt/α₀) K_i): the part of :meth:`jacobian` that depends on Δt only,
        kept for the last :meth:`matrix_key`."""
        key = ("constant", self.matrix_key(dt))
        held = self._shared.get("constant")
        if held is None or held[0] != key:
            st, s = self.stack, self.scheme
            J = st.mass * (s.inertia / dt)
            for m in st.matrices:
                if m.linear:
                    J = J + m.damping + m.stiffness * s.displacement_gain(dt)
            held = self._shared["constant"] = (key, sp.csr_matrix(J))
        return held[1]

    def response(self, loads: sp.spmatrix, dt: float | None = None) -> np.ndarray:
        """The change of V̄ that each column of ``loads`` (wall numbering) makes as a force F̄ of a step of Δt.

        The step of a linear wall is linear in its forces, so a load F̄ + ΔF̄ moves V̄ by
        A⁻¹ΔF̄ with A = :meth:`matrix` on the free DOFs: one back-substitution
        per column of the factors :meth:`step` uses (a dense wall × column array).

        Raises
        ------
        ValueError
            For a wall with a nonlinear layer, whose response depends on the load.
        """
        st, dt = self.stack, self.dt if dt is None else dt
        if not st.linear:
            raise ValueError("a wall with a nonlinear layer has no response independent of its load")
        out = np.zeros((st.space.ndofs, loads.shape[1]))
        out[st.free] = self._factors(dt).solve(loads.tocsr()[st.free].toarray())
        return out

    def _factors(self, dt: float):
        """The factorized matrix of Δt = ``dt``: factorized again when its coefficients change (:meth:`matrix_key`)."""
        key = self.matrix_key(dt)
        if self._shared["factors"] is None or self._shared["key"] != key:
            f = self.stack.free
            self._shared["factors"] = factorize(self.matrix(dt).tocsr()[f][:, f], self._stats, self._backend)
            self._shared["key"] = key
        return self._shared["factors"]

    def finish(self, states: Sequence[State], mean: np.ndarray, forces: Mapping[str, np.ndarray],
               dt: float | None = None, newton: NewtonResult | None = None) -> WallStep:
        """The new wall from V̄ solved (here or in a monolithic system), and the identity's terms.

        A nonlinear layer's elastic energy changes by what its force did, Σα_k d^{n+1−k}·f̂ = Δt V̄·f̂; what the
        scheme's stored energy does not take of it is numerical dissipation (:func:`elastic_remainder`).
        """
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
            if m.linear:
                elastic = s.numerical(m.elastic, ds)
            else:  # (Crank–Nicolson: the discrete gradient the last residual evaluated at this V̄, kept)
                elastic = elastic_remainder(s, m, ds, self._gradient(i, m, ds).force if midpoint(s) else None)
            numerical += s.numerical(m.kinetic, vs) + elastic
        dissipation["dissipation.numerical.wall"] = numerical
        work = {f"work.{name}": dt * float(mean @ f) for name, f in forces.items()}
        return WallStep(WallState(d, V), new_v, mean, stored, work, dissipation, newton)

    def energy(self, state: State) -> dict[str, float]:
        """Stored energy of every layer in ``state``, as the scheme measures it."""
        return wall_energy(self.stack, self.scheme, state, self.fluid_line)


def step_force(scheme: TimeScheme, forms: LayerMatrices, ds: Sequence[np.ndarray]) -> np.ndarray:
    """f̂: the internal force a layer's forms apply in a step of ``scheme`` with displacements ``ds`` (newest first).

    A linear layer's K d̄ at d̄ = Σβ_k d^{n+1−k}.  Otherwise it is what the
    scheme's energy identity needs (issue 38; the one place a scheme's kind
    matters to the wall):

    * the operator at one level (β = (1, 0, …): backward Euler, BDF2): the
      force there, f(d^{n+1}); what the stored energy's change leaves of its
      work is the scheme's numerical dissipation (:func:`elastic_remainder`;
      W(dⁿ) − W(d^{n+1}) + f(d^{n+1})·Δd ≥ 0 for backward Euler and a convex W);
    * the midpoint of two levels (Crank–Nicolson): the discrete gradient
      (Gonzalez 2000) f̄ = ∇W(d_mid) + [W(d¹) − W(d⁰) − ∇W(d_mid)·Δd] Δd/|Δd|²,
      so that f̄·Δd = W(d¹) − W(d⁰) and the step conserves W as it conserves
      ½dᵀKd (the correction is zero for a quadratic W, O(|Δd|²) otherwise;
      below :data:`GRADIENT_ROUND_OFF` of the energies it is round-off, left out).
      Its Δd is the layer's own: the wall's on the DOFs the layer's matrices
      touch, so that the correction stays on the layer.

    >>> import scipy.sparse as sp
    >>> from multilayer.numerics.timescheme import LinearMultistep
    >>> from multilayer.wall.layer import NonlinearForms
    >>> class Rule(LinearMultistep):  # a scheme's weights: the midpoint rule, BDF2
    ...     def __init__(self, name, alpha, beta):
    ...         self.name, self.alpha, self.beta = name, alpha, beta
    >>> midpoint, bdf2 = Rule("midpoint", (1.0, -1.0), (0.5, 0.5)), Rule("bdf2", (1.5, -2.0, 0.5), (1.0, 0.0, 0.0))
    >>> class Quartic(NonlinearForms):  # W = ¼ Σ d⁴
    ...     def elastic(self, d): return 0.25 * float(np.sum(d**4))
    ...     def force(self, d): return d**3
    >>> forms = Quartic(sp.identity(2, format="csr"), sp.csr_matrix((2, 2)), sp.csr_matrix((2, 2)))
    >>> d0, d1 = np.array([0.0, 1.0]), np.array([1.0, 2.0])
    >>> f = step_force(midpoint, forms, [d1, d0])
    >>> float(f @ (d1 - d0)) == forms.elastic(d1) - forms.elastic(d0), step_force(bdf2, forms, [d1, d0, d0])
    (True, array([1., 8.]))
    """
    if forms.linear or scheme.beta[0] == 1.0:
        return forms.force(scheme.average(ds))
    if not midpoint(scheme):
        raise ValueError(f"{scheme.name} has no energy-consistent internal force for a nonlinear layer: its "
                         f"operator is evaluated at Σβ_k d^(n+1−k) with β = {scheme.beta}")
    return discrete_gradient(forms, ds[0], ds[1]).force


def midpoint(scheme: TimeScheme) -> bool:
    """Whether ``scheme`` evaluates its operator at the midpoint of two levels (β = (½, ½): Crank–Nicolson), where a
    nonlinear layer's force is the discrete gradient."""
    return tuple(scheme.beta) == (0.5, 0.5)


def layer_dofs(forms: LayerMatrices) -> np.ndarray:
    """The DOFs (a boolean mask) a layer's mass or stiffness touches: where its discrete gradient's Δd is its own."""
    return (sp.csr_matrix(forms.mass).getnnz(axis=1) + sp.csr_matrix(forms.stiffness).getnnz(axis=1)) > 0


@attrs.frozen(eq=False)
class DiscreteGradient:
    """A layer's discrete gradient from d⁰ to d¹ (:func:`discrete_gradient`) and what its derivative needs."""

    midpoint: np.ndarray  #: ∇W(d_mid)
    delta: np.ndarray  #: Δd = d¹ − d⁰
    own: np.ndarray  #: Δd on the layer's DOFs
    norm2: float  #: |own|²
    coefficient: float  #: [W(d¹) − W(d⁰) − ∇W(d_mid)·Δd]/|own|², 0 where that is round-off
    before: float  #: W(d⁰)

    @property
    def force(self) -> np.ndarray:
        """f̄ = ∇W(d_mid) + coefficient · own."""
        return self.midpoint + self.coefficient * self.own if self.coefficient else self.midpoint


def discrete_gradient(forms: LayerMatrices, d1: np.ndarray, d0: np.ndarray, dofs: np.ndarray | None = None,
                      before: float | None = None) -> DiscreteGradient:
    """Gonzalez's discrete gradient of a layer's W from ``d0`` to ``d1`` (:func:`step_force`); ``dofs`` the layer's
    (:func:`layer_dofs`, found here when not given), ``before`` W(d0) when known."""
    f = forms.force(0.5 * (d0 + d1))
    delta = d1 - d0
    w1 = forms.elastic(d1)
    w0 = forms.elastic(d0) if before is None else before
    work = float(f @ delta)
    own = np.where(layer_dofs(forms) if dofs is None else dofs, delta, 0.0)
    jump, norm2 = w1 - w0 - work, float(own @ own)
    coefficient = 0.0
    if norm2 != 0.0 and abs(jump) > GRADIENT_ROUND_OFF * (abs(w1) + abs(w0) + abs(work)):
        coefficient = jump / norm2
    return DiscreteGradient(f, delta, own, norm2, coefficient, w0)


def gradient_derivative(forms: LayerMatrices, gradient: DiscreteGradient, K: sp.spmatrix, d1: np.ndarray,
                        dofs: np.ndarray) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """∂f̄/∂d¹ − ½K_T(d_mid) of a discrete gradient with a correction c = ``gradient.coefficient`` ≠ 0: a diagonal
    c·P (P the layer's DOFs) and a rank-one term own ⊗ ∇c, returned as (the diagonal, (own, ∇c)).

    With f̄ = f(m) + c·PΔ, c = j/|PΔ|², j = W(d¹) − W(d⁰) − f(m)·Δ and m = (d⁰ + d¹)/2:
    ∇c = [f(d¹) − f(m) − ½K_T(m)Δ − 2c·PΔ]/|PΔ|² (``K`` is K_T(m)).  The rank-one term is dense: it stays out of
    the sparse tangent (:meth:`StructureStep.jacobian`).
    """
    c, own = gradient.coefficient, gradient.own
    grad = (forms.force(d1) - gradient.midpoint - 0.5 * (K @ gradient.delta) - 2.0 * c * own) / gradient.norm2
    return c * dofs.astype(float), (own, grad)


def elastic_remainder(scheme: TimeScheme, forms: LayerMatrices, ds: Sequence[np.ndarray],
                      force: np.ndarray | None = None) -> float:
    """The numerical dissipation of a layer's elastic energy in a step: Σα_k d^{n+1−k}·f̂ − stored + before.

    The work of the force the step applied (:func:`step_force`) less the
    change of the energy the scheme stores; for a quadratic W it is the
    scheme's ``numerical`` (backward Euler: ½ΔdᵀKΔd), for Crank–Nicolson's
    discrete gradient zero to round-off.  BDF2's G-norm is an identity only
    for a quadratic W: with another the term may take either sign.
    """
    work = float(scheme.difference(ds) @ (step_force(scheme, forms, ds) if force is None else force))
    return work - scheme.stored(forms.elastic, ds) + scheme.before(forms.elastic, ds)


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


__all__ = ["DiscreteGradient", "StructureStep", "WallStep", "discrete_gradient", "elastic_remainder", "gradient_derivative",
           "layer_dofs", "midpoint", "own_velocity", "step_force", "wall_energy"]
