"""``tr-bdf2``: a trapezoidal stage, then a BDF2 stage: second order, L-stable, one step (Bank et al. 1985).

A step of Δt from tⁿ is two stages, γ = 2 − √2:

1. **the trapezoidal rule** (Crank–Nicolson) over γΔt, from xⁿ to x^{n+γ};
2. **BDF2** over (1 − γ)Δt through xⁿ, x^{n+γ} to x^{n+1}: variable-step BDF2 with the ratio
   ω = (1 − γ)/γ = 1/√2 of its sub-step to the trapezoidal one, α = (√2, −(1 + 1/√2), 1/(2 + √2)).

Both stages are schemes the couplers already step (the second is :class:`BDF2Stage`, BDF2 with the
identity below), and with this γ their matrices are the same: (α₀/β₀)/Δt_s = 2/(γΔt) = √2/((1 − γ)Δt)
for the mass and β₀Δt_s/α₀ = γΔt/2 for the stiffness, so a wall factorized for one serves the other.
The step is a one-step map xⁿ ↦ x^{n+1}: the second stage reads only levels of its own step.

Its energy identity is the stages' in a chain, each tested with its own x̄: the trapezoidal stage stores
q(x^{n+γ}) and dissipates nothing; the BDF2 stage starts from that (variable-step BDF2's identity with
ω₋ → 0, p₋ = 0: docs/theory.md, "Variable-step BDF2") and stores q(x^{n+1}) — it hands its G-norm's
excess E_ω(x^{n+1}, x^{n+γ}) − q(x^{n+1}) to its numerical dissipation — so each step starts from the
energy q(xⁿ) and a row of ``series.csv`` holds the energy itself.  On random vectors:

>>> import numpy as np
>>> M = np.diag([2.0, 3.0, 0.5]); q = lambda x: 0.5 * x @ M @ x
>>> rng = np.random.default_rng(0)
>>> (tr, *_), (bdf, *_) = TRBDF2().substeps(0.0, 1.0)
>>> x0, xg, x1 = (rng.normal(size=3) for _ in range(3))
>>> lhs = tr.difference([xg, x0]) @ M @ tr.average([xg, x0]) + bdf.difference([x1, xg, x0]) @ M @ x1
>>> rhs = q(x1) - q(x0) + tr.numerical(q, [xg, x0]) + bdf.numerical(q, [x1, xg, x0])
>>> bool(abs(lhs - rhs) < 1e-12), bool(TRBDF2().stored(q, [x1, x0]) == q(x1))
(True, True)
>>> [(type(s).__name__, round(a, 12), round(b, 12)) for s, a, b, _ in TRBDF2().substeps(0.0, 1.0)]
[('CrankNicolson', 0.0, 0.585786437627), ('BDF2Stage', 0.585786437627, 1.0)]
>>> [round(x, 12) for x in bdf.alpha], round(tr.inertia / 0.585786437627, 9) == round(bdf.inertia / (1 - 0.585786437627), 9)
([1.414213562373, -1.707106781187, 0.292893218813], True)

Unlike Crank–Nicolson it damps stiff modes: its amplification on x' = λx tends to 0 as λΔt → −∞
(L-stable; ``tests/test_tr_bdf2.py``), so no (−1)ⁿ mode survives a step.

Its local error estimate (docs/theory.md, "TR-BDF2"): on x' = f(t) a step's local error is
C Δt³ x''' with C = (3γ² − 4γ + 2)/(12(2 − γ)) ≈ 0.0404, the clock's predictor's
kₙ(kₙ + kₙ₋₁)(kₙ + kₙ₋₁ + kₙ₋₂)/6 x''', so, Milne's device as for the other schemes,

    e = C kₙ³ / (C kₙ³ + kₙ(kₙ + kₙ₋₁)(kₙ + kₙ₋₁ + kₙ₋₂)/6) · (x^{n+1} − x^p)      (0.0389 for equal steps).

>>> from multilayer.numerics.stepsize import local_error
>>> S = TRBDF2()
>>> round(S.milne([0.1, 0.1, 0.1]), 6), S.carried([0.1, 0.1, 0.1]), S.old_levels, S.order
(0.038868, 1.0, 2, 2)
>>> k, t = [0.2, 0.1, 0.05], np.array([0.35, 0.15, 0.05, 0.0])
>>> xs = [t[i] ** 3 / 6 for i in range(4)]                        # x''' = 1, uneven steps
>>> round(float(local_error(xs[0] + LOCAL_ERROR * k[0] ** 3, xs[1:], k, S) / (LOCAL_ERROR * k[0] ** 3)), 12)
1.0
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import ClassVar

import attrs
import numpy as np

from multilayer.numerics.timescheme import Quadratic, Stage, TimeScheme
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import SchemePlugin
from multilayer_plugins.schemes.bdf2 import BDF2
from multilayer_plugins.schemes.crank_nicolson import CrankNicolson

#: γ = 2 − √2: where the trapezoidal stage ends, the value that gives both stages the same matrix
GAMMA = 2.0 - math.sqrt(2.0)
#: C of the step's local error C Δt³ x''' (on x' = f(t): the stages' quadrature error)
LOCAL_ERROR = (3.0 * GAMMA**2 - 4.0 * GAMMA + 2.0) / (12.0 * (2.0 - GAMMA))


@attrs.frozen
class BDF2Stage(BDF2):
    """TR-BDF2's second stage: BDF2 through xⁿ, x^{n+γ}, x^{n+1} that stores q(x^{n+1}).

    The stage before it (the trapezoidal one) stored q(x^{n+γ}), not a G-norm: variable-step BDF2's
    identity with that start is its identity at ω₋ → 0 (p₋ = 0), and this stage keeps q(x^{n+1})
    as its stored energy, so the next step's trapezoidal stage starts from it.
    """

    def stored(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        return q(xs[0])

    def numerical(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        """BDF2's numerical dissipation from a start that stored q(x^{n+γ}), plus the G-norm's excess it hands
        over, E_ω(x^{n+1}, x^{n+γ}) − q(x^{n+1}): of either sign (docs/theory.md, "TR-BDF2")."""
        bdf2 = BDF2(ratio=self.ratio, previous=0.0)
        return bdf2.numerical(q, xs) + bdf2.stored(q, xs) - q(xs[0])


@attrs.frozen
class TRBDF2(TimeScheme):
    """A trapezoidal stage over γΔt, then a BDF2 stage over (1 − γ)Δt (module docstring)."""

    name: ClassVar[str] = "tr-bdf2"
    order: ClassVar[int] = 2
    alpha: ClassVar[tuple[float, ...]] = (1.0, -1.0)  # the step as a whole: xⁿ ↦ x^{n+1}
    estimates_error: ClassVar[bool] = True

    @property
    def stages(self) -> tuple[Stage, Stage]:
        """The trapezoidal stage (its old levels xⁿ, x^{n−1} a step Δt/ω apart: its ratio γω) and the BDF2 stage."""
        return (Stage(CrankNicolson(ratio=GAMMA * self.ratio), GAMMA),
                Stage(BDF2Stage(ratio=(1.0 - GAMMA) / GAMMA, previous=0.0), 1.0))

    def stored(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        """q(x^{n+1}): the energy its last stage stores."""
        return q(xs[0])

    def milne(self, k: Sequence[float]) -> float:
        c = LOCAL_ERROR * k[0] ** 3
        return c / (c + k[0] * (k[0] + k[1]) * (k[0] + k[1] + k[2]) / 6.0)


@hookimpl
def multilayer_schemes():
    return [SchemePlugin(name="tr-bdf2", factory=TRBDF2,
                         doc="TR-BDF2 (γ = 2 − √2): a trapezoidal stage, then a BDF2 stage; second order, L-stable, "
                             "one step; adaptive steps.")]
