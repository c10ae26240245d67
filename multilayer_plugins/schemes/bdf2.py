"""``bdf2``: the two-step backward differentiation formula, second order, with variable steps.

BDF2 differentiates the quadratic through x^{n+1}, xⁿ, x^{n−1} at t^{n+1}: with ω = Δtⁿ/Δtⁿ⁻¹ the step's
ratio to the one before,

    α = ((1 + 2ω)/(1 + ω), −(1 + ω), ω²/(1 + ω)),    β = (1, 0, 0),

(3/2, −2, ½) for constant steps; zero-stable for ω < 1 + √2 (:attr:`BDF2.max_ratio`; asking for more is
an error).  The fluid of a step is assembled on η^{n+1}, its loads averaged over one step centred on
t^{n+1}.

Its identity (docs/theory.md, "Variable-step BDF2") stores the G-norm
E_ω(x^{n+1}, xⁿ) = (1 − p) q(x^{n+1}) + p q(2x^{n+1} − xⁿ), p = ω/(1 + ω) (½ for constant steps); the old
level is measured as the step before stored it (its ratio ω₋), and the change of the G-norm from one
step to the next is part of the numerical dissipation, so the identity stays exact with changing Δt:

>>> import numpy as np
>>> M = np.diag([2.0, 3.0]); q = lambda x: 0.5 * x @ M @ x
>>> rng = np.random.default_rng(0)
>>> for ratio, before in [(1.0, 1.0), (1.7, 1.0), (0.4, 2.0), (2.0, 0.5)]:
...     v = BDF2().with_ratio(ratio, before)
...     xs = [rng.normal(size=2) for _ in range(3)]
...     lhs = v.difference(xs) @ M @ v.average(xs)
...     rhs = v.stored(q, xs) - v.before(q, xs) + v.numerical(q, xs)
...     print(ratio, bool(abs(lhs - rhs) < 1e-12))
1.0 True
1.7 True
0.4 True
2.0 True

Exact on quadratics with uneven steps (Δtⁿ = 0.2 after Δtⁿ⁻¹ = 0.1): Σα_k x^{n+1−k}/Δt = x'(t^{n+1}).

>>> s = BDF2().with_ratio(2.0)
>>> [round(a, 12) for a in s.alpha], sum(s.alpha)
([1.666666666667, -3.0, 1.333333333333], 0.0)
>>> t = [0.3, 0.1, 0.0]
>>> [round(float(s.difference([f(x) for x in t]) / 0.2), 12) for f in (lambda x: 1.0 + 0 * x,
...                                                                    lambda x: x, lambda x: x * x)]
[0.0, 1.0, 0.6]
>>> BDF2().with_ratio(2.5)
Traceback (most recent call last):
...
ValueError: bdf2 is stable for step ratios below 2.414 (1 + √2), got 2.5

Its local error estimate (docs/theory.md, "Adaptive steps"): the corrector's local error is
kₙ²(kₙ + kₙ₋₁)/(6α₀) x''', the clock's predictor's kₙ(kₙ + kₙ₋₁)(kₙ + kₙ₋₁ + kₙ₋₂)/6 x''', so

    e = kₙ / (kₙ + α₀(kₙ + kₙ₋₁ + kₙ₋₂)) · (x^{n+1} − x^p)      (2/11 for equal steps),

and a step adds α₀ times its local error to the run's (smooth) error (:meth:`BDF2.carried`).

>>> round(BDF2().milne([0.1, 0.1, 0.1]), 12), round(BDF2().milne([0.2, 0.1, 0.1]), 12)   # ω = 2: 3/13
(0.181818181818, 0.230769230769)
>>> BDF2().carried([0.1, 0.1, 0.1]), BDF2().old_levels, BDF2().geometry_position
(1.5, 2, 1.0)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import ClassVar

import attrs
import numpy as np

from multilayer.numerics.timescheme import Quadratic, TimeScheme
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import SchemePlugin


def bdf2_alpha(w: float) -> tuple[float, float, float]:
    """Variable-step BDF2's α for the step ratio ω (the constant step's (3/2, −2, 1/2) at ω = 1, exactly).

    >>> bdf2_alpha(1.0), bdf2_alpha(2.0)[0]
    ((1.5, -2.0, 0.5), 1.6666666666666667)
    """
    return (1.5, -2.0, 0.5) if w == 1.0 else ((1.0 + 2.0 * w) / (1.0 + w), -(1.0 + w), w * w / (1.0 + w))


@attrs.frozen
class BDF2(TimeScheme):
    """x̄ = x^{n+1}: (α₀x^{n+1} + α₁xⁿ + α₂x^{n−1})/Δt·M + A x^{n+1} = F̄, α of the step's ratio."""

    name: ClassVar[str] = "bdf2"
    order: ClassVar[int] = 2
    beta: ClassVar[tuple[float, ...]] = (1.0, 0.0, 0.0)
    estimates_error: ClassVar[bool] = True
    adaptive_energy_note: ClassVar[str] = (
        " — or not: with adaptive steps, bdf2's energy may exceed E⁰ + work by a few percent of the work while "
        "the steps grow, without instability (its G-norm depends on the step ratio: docs/theory.md, "
        "'Variable-step BDF2'); set solver.energy_margin = 0.05")

    @property
    def alpha(self) -> tuple[float, float, float]:
        return bdf2_alpha(self.ratio)

    def with_ratio(self, ratio: float, previous: float = 1.0) -> BDF2:
        """BDF2 for a step ω = ``ratio`` times the one before: its α changes with ω (module docstring)."""
        if not 0.0 < ratio < self.max_ratio:
            raise ValueError(f"{self.name} is stable for step ratios below {self.max_ratio:.4g} (1 + √2), "
                             f"got {ratio:g}")
        return super().with_ratio(ratio, previous)

    @property
    def max_ratio(self) -> float:
        """1 + √2: variable-step BDF2 is zero-stable for ω below it (Grigorieff 1983)."""
        return 1.0 + math.sqrt(2.0)

    def geometry(self, etas: Sequence[np.ndarray]) -> np.ndarray:
        """η^{n+1}."""
        return etas[0]

    def stored(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        """(1 − p) q(x^{n+1}) + p q(2x^{n+1} − xⁿ) with p = ω/(1 + ω)."""
        if self.ratio == 1.0:
            return 0.5 * (q(xs[0]) + q(2.0 * xs[0] - xs[1]))
        p = self.ratio / (1.0 + self.ratio)
        return (1.0 - p) * q(xs[0]) + p * q(2.0 * xs[0] - xs[1])

    def numerical(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        """With u = x^{n+1} − xⁿ, w = xⁿ − x^{n−1}, b = ω²/(1 + ω), p₋ = ω₋/(1 + ω₋) (ω₋ the step before's ratio):

            (1 − ω) q(u) + b q(u − w) + (p₋ − b)(q(2xⁿ − x^{n−1}) − q(xⁿ)),

        ½q(x^{n+1} − 2xⁿ + x^{n−1}) ≥ 0 for constant steps; a growing step (ω > 1) and a change of
        ratio (the G-norm's change, the last term) make it of either sign.
        """
        if self.ratio == 1.0 and self.previous == 1.0:
            return 0.5 * q(xs[0] - 2.0 * xs[1] + xs[2])
        w, u, v = self.ratio, xs[0] - xs[1], xs[1] - xs[2]
        b, p = w * w / (1.0 + w), self.previous / (1.0 + self.previous)
        return (1.0 - w) * q(u) + b * q(u - v) + (p - b) * (q(2.0 * xs[1] - xs[2]) - q(xs[1]))

    def milne(self, k: Sequence[float]) -> float:
        return k[0] / (k[0] + bdf2_alpha(k[0] / k[1])[0] * (k[0] + k[1] + k[2]))

    def carried(self, k: Sequence[float]) -> float:
        """α₀ of the step's ratio kₙ/kₙ₋₁.

        BDF2's error recursion α₀(eⁿ⁺¹ − eⁿ) − α₂(eⁿ − eⁿ⁻¹) = kₙτ + …, for a smooth error
        (eⁿ − eⁿ⁻¹ ≈ (eⁿ⁺¹ − eⁿ)/ω), is (α₀ − α₂/ω)(eⁿ⁺¹ − eⁿ) = eⁿ⁺¹ − eⁿ = kₙτ: a step adds its
        truncation error kₙτ = α₀ · (its local error), not the local error itself.
        """
        return bdf2_alpha(k[0] / k[1])[0]


@hookimpl
def multilayer_schemes():
    return [SchemePlugin(name="bdf2", factory=BDF2,
                         doc="BDF2, variable-step: second order, A-stable, dissipative (a G-norm); adaptive steps.")]
