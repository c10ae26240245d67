"""``crank-nicolson``: α = (1, −1), β = (½, ½), second order, no numerical dissipation.

Solved as the refactorized midpoint rule: a backward-Euler step of Δt/2 for x̄, then x^{n+1} = 2x̄ − xⁿ.
Its identity, (a − b)·(a + b) = |a|² − |b|²: it stores q(x^{n+1}) and dissipates nothing, with every
step's own Δt (a one-step rule: a change of step size changes nothing in it).  The fluid of a step is
assembled on the midpoint domain (ηⁿ + η^{n+1})/2.  It carries stiff modes undamped, as (−1)ⁿ
oscillations, so the clock drops their echo from its error estimate (``undamped``).

Its local error estimate (docs/theory.md, "Adaptive steps"): the corrector's local error is
kₙ³/12 x''', the clock's predictor's kₙ(kₙ + kₙ₋₁)(kₙ + kₙ₋₁ + kₙ₋₂)/6 x''', so

    e = kₙ² / (kₙ² + 2(kₙ + kₙ₋₁)(kₙ + kₙ₋₁ + kₙ₋₂)) · (x^{n+1} − x^p)      (1/13 for equal steps).

>>> import numpy as np
>>> from multilayer.numerics.stepsize import local_error
>>> S = CrankNicolson()
>>> round(S.milne([0.1, 0.1, 0.1]), 12), S.carried([0.1, 0.1, 0.1])
(0.076923076923, 1.0)
>>> k, t = [0.1, 0.1, 0.1], np.array([0.3, 0.2, 0.1, 0.0])
>>> xs = [t[i] ** 3 / 6 for i in range(4)]                        # x''' = 1
>>> round(float(local_error(xs[0] + k[0] ** 3 / 12, xs[1:], k, S) / (k[0] ** 3 / 12)), 12)
1.0
>>> S.with_ratio(2.0).extrapolate([1.0, 0.0]), S.geometry_position, S.load_window(0.0, 0.1)
(2.0, 0.5, (0.0, 0.1))
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import attrs
import numpy as np

from multilayer.numerics.timescheme import Quadratic, TimeScheme
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import SchemePlugin


@attrs.frozen
class CrankNicolson(TimeScheme):
    """x̄ = (x^{n+1} + xⁿ)/2: (x^{n+1} − xⁿ)/Δt·M + A x̄ = F̄."""

    name: ClassVar[str] = "crank-nicolson"
    order: ClassVar[int] = 2
    alpha: ClassVar[tuple[float, ...]] = (1.0, -1.0)
    beta: ClassVar[tuple[float, ...]] = (0.5, 0.5)
    estimates_error: ClassVar[bool] = True
    undamped: ClassVar[bool] = True

    def geometry(self, etas: Sequence[np.ndarray]) -> np.ndarray:
        """The midpoint (η^{n+1} + ηⁿ)/2."""
        return self.average(etas)

    def stored(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        return q(xs[0])

    def numerical(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        """None: the midpoint rule conserves q."""
        return 0.0

    def milne(self, k: Sequence[float]) -> float:
        return k[0] ** 2 / (k[0] ** 2 + 2.0 * (k[0] + k[1]) * (k[0] + k[1] + k[2]))


@hookimpl
def multilayer_schemes():
    return [SchemePlugin(name="crank-nicolson", factory=CrankNicolson,
                         doc="Crank–Nicolson (refactorized midpoint rule): second order, no numerical dissipation; "
                             "adaptive steps.")]
