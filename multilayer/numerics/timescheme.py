"""Time discretizations as values, each with its discrete energy identity.

A scheme is a linear multistep rule with coefficients α (the difference
quotient) and β (where the operator is evaluated), levels newest first:

    Σ_k α_k x^{n+1−k} / Δt · M  +  A x̄  =  F̄,      x̄ = Σ_k β_k x^{n+1−k}.

Every sub-problem of the project (a wall step, a fluid step, both at once)
is solved for the *test-level* unknown x̄: the matrix is
(α₀/β₀) M/Δt + A and only old levels move to the right-hand side.  For
Crank–Nicolson x̄ is the midpoint value and the step is a backward-Euler
step of Δt/2 followed by the extrapolation x^{n+1} = 2x̄ − xⁿ (the
refactorized midpoint rule); for backward Euler and BDF2, x̄ = x^{n+1}.

Testing with x̄ gives the energy identity of the scheme, for q(x) = ½xᵀMx:

    (Σ_k α_k x^{n+1−k})ᵀ M x̄ = stored(q, xⁿ⁺¹…) − stored(q, xⁿ…) + numerical(q, xⁿ⁺¹…)

where ``stored`` is the energy the scheme conserves (q itself for backward
Euler and Crank–Nicolson, the G-norm ½(q(x^{n+1}) + q(2x^{n+1} − xⁿ)) for
BDF2) and ``numerical`` ≥ 0 is its numerical dissipation (zero for
Crank–Nicolson).

>>> import numpy as np
>>> M = np.diag([2.0, 3.0]); q = lambda x: 0.5 * x @ M @ x
>>> rng = np.random.default_rng(0)
>>> for s in SCHEMES.values():
...     xs = [rng.normal(size=2) for _ in range(s.levels)]
...     lhs = s.difference(xs) @ M @ s.average(xs)
...     rhs = s.stored(q, xs) - s.stored(q, xs[1:] + xs[-1:]) + s.numerical(q, xs)
...     print(s.name, abs(lhs - rhs) < 1e-12)
backward-euler True
crank-nicolson True
bdf2 True
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import attrs
import numpy as np

from multilayer.plugin.records import Param

Quadratic = Callable[[np.ndarray], float]


@attrs.frozen
class TimeScheme:
    """One linear multistep rule.  See the module docstring.

    Parameters
    ----------
    name : str
        The name a case file uses.
    alpha, beta : tuple of float
        Coefficients of x^{n+1}, xⁿ, x^{n−1}, ... (Σα = 0, Σβ = 1).
    order : int
        Order of accuracy in time.
    ratio : float
        ω = Δtⁿ/Δtⁿ⁻¹, the step's ratio to the one before (1 for constant steps): only the
        extrapolations see it, Crank–Nicolson's α and β do not depend on it (:meth:`with_ratio`).
    """

    name: str
    alpha: tuple[float, ...]
    beta: tuple[float, ...]
    order: int
    ratio: float = 1.0

    def with_ratio(self, ratio: float) -> TimeScheme:
        """This rule for a step ω = ``ratio`` times the one before.

        One-step rules keep their coefficients (Crank–Nicolson's identity holds
        step by step with that step's Δt); BDF2's would change with ω, which is
        not offered, so asking for it is an error.

        >>> SCHEMES["crank-nicolson"].with_ratio(2.0).extrapolate([1.0, 0.0])
        2.0
        """
        if ratio != 1.0 and self.levels > 2:
            raise ValueError(f"{self.name} has no variable-step coefficients here; only one-step rules change Δt")
        return attrs.evolve(self, ratio=float(ratio))

    @property
    def levels(self) -> int:
        """Time levels the rule involves, the new one included."""
        return len(self.alpha)

    @property
    def old_levels(self) -> int:
        """Old levels a step needs: the rule's, and two for a second-order scheme's extrapolations.

        >>> [s.old_levels for s in SCHEMES.values()]
        [1, 2, 2]
        """
        return max(len(self.alpha) - 1, self.order)

    @property
    def theta(self) -> float:
        """Where the operator is evaluated, as a fraction of the step: t = tⁿ + θΔt.

        >>> SCHEMES["crank-nicolson"].theta, SCHEMES["bdf2"].theta
        (0.5, 1.0)
        """
        return float(sum(b * (1 - k) for k, b in enumerate(self.beta)))

    @property
    def inertia(self) -> float:
        """α₀/β₀: the matrix of the step is inertia·M/Δt + A.  Δt/inertia is the step of the
        equivalent backward-Euler solve (Δt/2 for Crank–Nicolson)."""
        return self.alpha[0] / self.beta[0]

    # -- the rule ----------------------------------------------------------------
    def difference(self, xs: Sequence[np.ndarray]) -> np.ndarray:
        """Σ α_k x^{n+1−k} (Δt times the discrete time derivative); ``xs`` newest first."""
        return sum(a * x for a, x in zip(self.alpha, xs))

    def average(self, xs: Sequence[np.ndarray]) -> np.ndarray:
        """x̄ = Σ β_k x^{n+1−k}: the level the operator sees and the identity tests with."""
        return sum(b * x for b, x in zip(self.beta, xs))

    def history(self, old: Sequence[np.ndarray]) -> np.ndarray:
        """h with Σ α_k x^{n+1−k} = (α₀/β₀) x̄ + h, from the old levels xⁿ, x^{n−1}, ... alone."""
        a0b0 = self.inertia
        return sum((a - a0b0 * b) * x for a, b, x in zip(self.alpha[1:], self.beta[1:], old))

    def new_level(self, xbar: np.ndarray, old: Sequence[np.ndarray]) -> np.ndarray:
        """x^{n+1} from the solved x̄ and the old levels."""
        return (xbar - sum(b * x for b, x in zip(self.beta[1:], old))) / self.beta[0]

    def displacement(self, vbar: np.ndarray, old: Sequence[np.ndarray], dt: float) -> np.ndarray:
        """d^{n+1} from Σ α_k d^{n+1−k} = Δt v̄ (the displacement the velocity x̄ integrates to)."""
        return (dt * vbar - sum(a * d for a, d in zip(self.alpha[1:], old))) / self.alpha[0]

    def displacement_gain(self, dt: float) -> float:
        """∂d̄/∂v̄ = β₀Δt/α₀: the operator sees d̄ = Σβ_k d^{n+1−k} = gain·v̄ + (the old levels' share)."""
        return self.beta[0] * dt / self.alpha[0]

    def displacement_average_history(self, old_d: Sequence[np.ndarray]) -> np.ndarray:
        """The part of d̄ = Σβ_k d^{n+1−k} that the old displacements give (v̄ = 0)."""
        b0, a0 = self.beta[0], self.alpha[0]
        return sum((b - b0 * a / a0) * d for a, b, d in zip(self.alpha[1:], self.beta[1:], old_d))

    def extrapolate(self, old: Sequence[np.ndarray]) -> np.ndarray:
        """x at tⁿ + θΔt from the old levels, to the scheme's order (xⁿ for first order).

        The old levels are Δtⁿ⁻¹ = Δt/ω apart: x̃ = xⁿ + θω(xⁿ − xⁿ⁻¹).

        A second-order scheme needs :attr:`old_levels` = 2 levels here: with
        one it would silently be first order, so that is an error.
        """
        if self.order == 1:
            return old[0]
        if len(old) < 2:
            raise ValueError(f"{self.name} extrapolates from two old levels, got {len(old)}")
        return old[0] + self.theta * self.ratio * (old[0] - old[1])

    def geometry(self, etas: Sequence[np.ndarray]) -> np.ndarray:
        """The wall displacement a fluid step is assembled on, from η^{n+1}, ηⁿ (newest first).

        Backward Euler: ηⁿ, the old domain (the kinematically coupled
        scheme's choice: with ∂_t J = (J^{n+1} − Jⁿ)/Δt it leaves no
        geometric remainder); Crank–Nicolson: the midpoint; BDF2: η^{n+1}.
        """
        if self.name == "backward-euler":
            return etas[1]
        return self.average(etas) if self.name == "crank-nicolson" else etas[0]

    @property
    def geometry_position(self) -> float:
        """Where the domain of :meth:`geometry` sits in the step, as a fraction: tⁿ + position·Δt.

        >>> [s.geometry_position for s in SCHEMES.values()]
        [0.0, 0.5, 1.0]
        """
        return float(self.geometry([np.ones(1), np.zeros(1), np.zeros(1)])[0])

    def load_window(self, t0: float, t1: float) -> tuple[float, float]:
        """The time window whose average load is F̄.

        [tⁿ, tⁿ⁺¹] for backward Euler (theory §6: the time average over the
        step) and Crank–Nicolson (centred on its midpoint); for BDF2 one step
        centred on tⁿ⁺¹, where its operator is evaluated.
        """
        if self.order == 1:
            return t0, t1
        centre = t0 + self.theta * (t1 - t0)
        half = 0.5 * (t1 - t0)
        return centre - half, centre + half

    # -- the energy identity -------------------------------------------------------
    def stored(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        """The energy the scheme's identity carries at the newest level of ``xs``."""
        if self.name == "bdf2":
            return 0.5 * (q(xs[0]) + q(2.0 * xs[0] - xs[1]))
        return q(xs[0])

    def numerical(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        """Numerical dissipation of one step (≥ 0 for a positive semi-definite q)."""
        if self.name == "backward-euler":
            return q(xs[0] - xs[1])
        if self.name == "bdf2":
            return 0.5 * q(xs[0] - 2.0 * xs[1] + xs[2])
        return 0.0


SCHEMES: dict[str, TimeScheme] = {
    s.name: s
    for s in (
        TimeScheme("backward-euler", (1.0, -1.0), (1.0, 0.0), 1),
        TimeScheme("crank-nicolson", (1.0, -1.0), (0.5, 0.5), 2),
        TimeScheme("bdf2", (1.5, -2.0, 0.5), (1.0, 0.0, 0.0), 2),
    )
}


def scheme_param(choices: Sequence[str], default: str = "backward-euler") -> Param:
    """The ``scheme`` parameter of a coupler that offers ``choices``."""
    return Param("scheme", type=str, default=default, choices=tuple(choices),
                 doc="time discretization: " + ", ".join(choices))


def levels(x: np.ndarray, history: Sequence[np.ndarray], n: int) -> list[np.ndarray]:
    """[x, history[0], ...] padded to ``n`` levels by repeating the oldest (rest before t = 0)."""
    out = [x, *history][:n]
    while len(out) < n:
        out.append(out[-1])
    return out
