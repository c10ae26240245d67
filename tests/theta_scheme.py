"""A time scheme from outside the package: the θ-method, registered by hand (``--plugin``, ``Registry.load(extra=)``).

x̄ = θx^{n+1} + (1 − θ)xⁿ: α = (1, −1), β = (θ, 1 − θ); θ = 1 is backward Euler's weights, θ = ½
Crank–Nicolson's.  First order for θ ≠ ½.  Its identity, for a = x^{n+1}, b = xⁿ:

    (a − b)·M(θa + (1 − θ)b) = q(a) − q(b) + (2θ − 1) q(a − b),

so it stores q(x^{n+1}) and dissipates (2θ − 1) q(x^{n+1} − xⁿ) ≥ 0 for θ ≥ ½.  The fluid of a step is
assembled on the domain at the θ-point, θη^{n+1} + (1 − θ)ηⁿ.  It has no error estimate (no adaptive
steps) and is one module with no edit in ``multilayer/``: ``tests/test_timescheme.py`` runs it under
every coupler.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import attrs
import numpy as np

from multilayer.numerics.timescheme import Quadratic, TimeScheme
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import Param, SchemePlugin


@attrs.frozen
class Theta(TimeScheme):
    """The θ-method (module docstring)."""

    theta: float = 1.0

    name: ClassVar[str] = "theta"
    alpha: ClassVar[tuple[float, ...]] = (1.0, -1.0)

    @property
    def beta(self) -> tuple[float, float]:
        return (self.theta, 1.0 - self.theta)

    @property
    def order(self) -> int:
        return 2 if self.theta == 0.5 else 1

    def geometry(self, etas: Sequence[np.ndarray]) -> np.ndarray:
        return self.average(etas)

    def stored(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        return q(xs[0])

    def numerical(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        return (2.0 * self.theta - 1.0) * q(xs[0] - xs[1])


@hookimpl
def multilayer_schemes():
    return [SchemePlugin(name="theta", factory=Theta,
                         params=(Param("theta", "θ", "1", default=1.0, ge=0.5, le=1.0,
                                       doc="where the operator is evaluated: x̄ = θx^{n+1} + (1 − θ)xⁿ"),),
                         doc="The θ-method (a test's plugin): θ = 1 backward Euler's weights, ½ Crank–Nicolson's.")]
