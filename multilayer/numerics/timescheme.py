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

    (Σ_k α_k x^{n+1−k})ᵀ M x̄ = stored(q, xⁿ⁺¹…) − before(q, xⁿ⁺¹…) + numerical(q, xⁿ⁺¹…)

where ``stored`` is the energy the scheme carries at the new level (q itself
for backward Euler and Crank–Nicolson, the G-norm ½(q(x^{n+1}) + q(2x^{n+1} − xⁿ))
for BDF2), ``before`` the same at the old level as the step before stored it,
and ``numerical`` the numerical dissipation (≥ 0 for constant steps, zero for
Crank–Nicolson).  Variable-step BDF2 (:meth:`TimeScheme.with_ratio`, docs/theory.md
"Variable-step BDF2") has a G-norm that depends on the step ratio ω; the change
of it from one step to the next is part of ``numerical``, so the identity stays
exact with changing Δt.

>>> import numpy as np
>>> M = np.diag([2.0, 3.0]); q = lambda x: 0.5 * x @ M @ x
>>> rng = np.random.default_rng(0)
>>> ratios = {"bdf2": [(1.0, 1.0), (1.7, 1.0), (0.4, 2.0), (2.0, 0.5)]}
>>> for s in SCHEMES.values():
...     for ratio, before in ratios.get(s.name, [(1.0, 1.0)]):
...         v = s.with_ratio(ratio, before)
...         xs = [rng.normal(size=2) for _ in range(s.levels)]
...         lhs = v.difference(xs) @ M @ v.average(xs)
...         rhs = v.stored(q, xs) - v.before(q, xs) + v.numerical(q, xs)
...         print(s.name, ratio, abs(lhs - rhs) < 1e-12)
backward-euler 1.0 True
crank-nicolson 1.0 True
bdf2 1.0 True
bdf2 1.7 True
bdf2 0.4 True
bdf2 2.0 True
"""

from __future__ import annotations

import math
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
        ω = Δtⁿ/Δtⁿ⁻¹, the step's ratio to the one before (1 for constant steps): the
        extrapolations see it, and BDF2's α (:meth:`with_ratio`).
    previous : float
        The ratio of the step before (BDF2's G-norm of the old level is that step's).
    """

    name: str
    alpha: tuple[float, ...]
    beta: tuple[float, ...]
    order: int
    ratio: float = 1.0
    previous: float = 1.0

    def with_ratio(self, ratio: float, previous: float = 1.0) -> TimeScheme:
        """This rule for a step ω = ``ratio`` times the one before, which was ``previous`` times its own.

        One-step rules keep their coefficients (Crank–Nicolson's identity holds
        step by step with that step's Δt).  BDF2 differentiates the quadratic
        through x^{n+1}, xⁿ, x^{n−1} at t^{n+1}:

            α = ((1 + 2ω)/(1 + ω), −(1 + ω), ω²/(1 + ω)),

        zero-stable for ω < 1 + √2 (:attr:`max_ratio`; asking for more is an error).

        >>> SCHEMES["crank-nicolson"].with_ratio(2.0).extrapolate([1.0, 0.0])
        2.0
        >>> s = SCHEMES["bdf2"].with_ratio(2.0)
        >>> [round(a, 12) for a in s.alpha], sum(s.alpha)
        ([1.666666666667, -3.0, 1.333333333333], 0.0)

        Exact on quadratics with uneven steps (Δtⁿ = 0.2 after Δtⁿ⁻¹ = 0.1): Σα_k x^{n+1−k}/Δt = x'(t^{n+1}).

        >>> t = [0.3, 0.1, 0.0]
        >>> [round(float(s.difference([f(x) for x in t]) / 0.2), 12) for f in (lambda x: 1.0 + 0 * x,
        ...                                                                    lambda x: x, lambda x: x * x)]
        [0.0, 1.0, 0.6]
        >>> SCHEMES["bdf2"].with_ratio(2.5)
        Traceback (most recent call last):
        ...
        ValueError: bdf2 is stable for step ratios below 2.414 (1 + √2), got 2.5
        """
        if self.levels <= 2:
            return attrs.evolve(self, ratio=float(ratio), previous=float(previous))
        if not 0.0 < ratio < self.max_ratio:
            raise ValueError(f"{self.name} is stable for step ratios below {self.max_ratio:.4g} (1 + √2), "
                             f"got {ratio:g}")
        w = float(ratio)
        return attrs.evolve(self, alpha=bdf2_alpha(w), ratio=w, previous=float(previous))

    @property
    def max_ratio(self) -> float:
        """The largest step ratio ω the rule takes: 1 + √2 for BDF2 (zero stability), none for one-step rules."""
        return 1.0 + math.sqrt(2.0) if self.levels > 2 else math.inf

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
        """The energy the scheme's identity carries at the newest level of ``xs``.

        BDF2: (1 − p) q(x^{n+1}) + p q(2x^{n+1} − xⁿ) with p = ω/(1 + ω) (½ for constant steps).
        """
        if self.name != "bdf2":
            return q(xs[0])
        if self.ratio == 1.0:
            return 0.5 * (q(xs[0]) + q(2.0 * xs[0] - xs[1]))
        p = self.ratio / (1.0 + self.ratio)
        return (1.0 - p) * q(xs[0]) + p * q(2.0 * xs[0] - xs[1])

    def before(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        """The energy at the old level xⁿ of ``xs`` (newest first) as the step before stored it (its ratio)."""
        if self.name != "bdf2" or self.previous == self.ratio:
            return self.stored(q, xs[1:])
        return attrs.evolve(self, ratio=self.previous).stored(q, xs[1:])

    def numerical(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        """Numerical dissipation of one step: Σα_k x^{n+1−k}·M x̄ − stored + before.

        Backward Euler: q(x^{n+1} − xⁿ).  BDF2 (docs/theory.md, "Variable-step BDF2"), with
        u = x^{n+1} − xⁿ, w = xⁿ − x^{n−1}, b = ω²/(1 + ω), p₋ = ω₋/(1 + ω₋) (ω₋ the step before's ratio):

            (1 − ω) q(u) + b q(u − w) + (p₋ − b)(q(2xⁿ − x^{n−1}) − q(xⁿ)),

        ½q(x^{n+1} − 2xⁿ + x^{n−1}) ≥ 0 for constant steps; a growing step (ω > 1) and a change of
        ratio (the G-norm's change, the last term) make it of either sign.
        """
        if self.name == "backward-euler":
            return q(xs[0] - xs[1])
        if self.name != "bdf2":
            return 0.0
        if self.ratio == 1.0 and self.previous == 1.0:
            return 0.5 * q(xs[0] - 2.0 * xs[1] + xs[2])
        w, u, v = self.ratio, xs[0] - xs[1], xs[1] - xs[2]
        b, p = w * w / (1.0 + w), self.previous / (1.0 + self.previous)
        return (1.0 - w) * q(u) + b * q(u - v) + (p - b) * (q(2.0 * xs[1] - xs[2]) - q(xs[1]))


def bdf2_alpha(w: float) -> tuple[float, float, float]:
    """Variable-step BDF2's α = ((1 + 2ω)/(1 + ω), −(1 + ω), ω²/(1 + ω)) for the step ratio ω (the constant
    step's (3/2, −2, 1/2) at ω = 1, exactly).

    >>> bdf2_alpha(1.0), bdf2_alpha(2.0)[0]
    ((1.5, -2.0, 0.5), 1.6666666666666667)
    """
    return (1.5, -2.0, 0.5) if w == 1.0 else ((1.0 + 2.0 * w) / (1.0 + w), -(1.0 + w), w * w / (1.0 + w))


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
