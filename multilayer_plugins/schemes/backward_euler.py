"""``backward-euler``: α = (1, −1), β = (1, 0), first order, the paper's scheme.

Its identity, 2(a − b)·a = |a|² − |b|² + |a − b|²: it stores q(x^{n+1}) and dissipates q(x^{n+1} − xⁿ) ≥ 0.
The fluid of a step is assembled on the old domain ηⁿ: with ∂_t J = (J^{n+1} − Jⁿ)/Δt that leaves no
geometric remainder (the kinematically coupled scheme's choice, docs/theory.md §5).  First order: no
second-order pair to estimate its error with, so no adaptive steps.

>>> import numpy as np
>>> M = np.diag([2.0, 3.0]); q = lambda x: 0.5 * x @ M @ x
>>> S, xs = BackwardEuler(), [np.array([1.0, 2.0]), np.array([0.5, -1.0])]
>>> lhs = S.difference(xs) @ M @ S.average(xs)
>>> bool(abs(lhs - (S.stored(q, xs) - S.before(q, xs) + S.numerical(q, xs))) < 1e-12)
True
>>> S.geometry_position, S.old_levels, S.load_window(0.0, 0.1)
(0.0, 1, (0.0, 0.1))
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
class BackwardEuler(TimeScheme):
    """x̄ = x^{n+1}: (x^{n+1} − xⁿ)/Δt·M + A x^{n+1} = F̄."""

    name: ClassVar[str] = "backward-euler"
    order: ClassVar[int] = 1
    alpha: ClassVar[tuple[float, ...]] = (1.0, -1.0)
    beta: ClassVar[tuple[float, ...]] = (1.0, 0.0)

    def geometry(self, etas: Sequence[np.ndarray]) -> np.ndarray:
        """ηⁿ: the old domain."""
        return etas[1]

    def stored(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        return q(xs[0])

    def numerical(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        """q(x^{n+1} − xⁿ)."""
        return q(xs[0] - xs[1])


@hookimpl
def multilayer_schemes():
    return [SchemePlugin(name="backward-euler", factory=BackwardEuler,
                         doc="Backward Euler: first order, dissipative (the paper's scheme); fluid on the old domain.")]
