"""Steps chosen by error: the local error estimate of a step, and the step-size controller.

The estimate (derivation in docs/theory.md, "Adaptive steps") compares the
corrector's value x^{n+1} with an explicit AB2-type predictor built from
levels the run already has: the midpoint difference quotients
Dⁿ = (xⁿ − xⁿ⁻¹)/kₙ₋₁ and Dⁿ⁻¹ = (xⁿ⁻¹ − xⁿ⁻²)/kₙ₋₂ stand at tⁿ⁻½ and tⁿ⁻³ᐟ²;
extrapolated linearly to tⁿ⁺½ they give

    x^p = xⁿ + kₙ (Dⁿ + (kₙ + kₙ₋₁)/(kₙ₋₁ + kₙ₋₂) (Dⁿ − Dⁿ⁻¹)),

exact for quadratics (AB2 with midpoint slopes; it is the quadratic through
xⁿ⁻², xⁿ⁻¹, xⁿ evaluated at tⁿ⁺¹).  Its error is, to leading order,

    x(tⁿ⁺¹) − x^p = P x''',    P = kₙ(kₙ + kₙ₋₁)(kₙ + kₙ₋₁ + kₙ₋₂)/6,

and a second-order corrector's local error is x^{n+1} − x(tⁿ⁺¹) = c x''' with a constant c of its
own (Crank–Nicolson's kₙ³/12, BDF2's kₙ²(kₙ + kₙ₋₁)/(6α₀)), so the local error is the computed
difference scaled (Milne's device): e = c/(c + P) · (x^{n+1} − x^p).  The scheme owns that factor
(:meth:`TimeScheme.milne <multilayer.numerics.timescheme.TimeScheme.milne>`) and how much of a step's
local error stays in the run's error (:meth:`~multilayer.numerics.timescheme.TimeScheme.carried`).
No linear solve: the predictor is three old levels.

>>> t = [0.2, 0.1, 0.0]; k = [0.1, 0.1, 0.1]
>>> round(float(predictor([x * x for x in t], k)), 12)      # exact for quadratics: 0.3²
0.09
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import attrs
import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from multilayer.numerics.timescheme import TimeScheme

#: the controller's exponents (Gustafsson's PI controller as in Hairer & Wanner, II §IV.2): the step
#: factor is SAFETY · err^(−KI/q) · err_prev^(KP/q), q = 3 for the error per step of a second-order rule (q = 2
#: per unit step)
KI, KP = 0.7, 0.4
SAFETY = 0.9
#: bounds of the factor after an accepted step, and after a rejected one
GROW, SHRINK, REJECT_MIN = 2.0, 0.2, 0.1
#: an accepted step's factor in [1, KEEP) keeps Δt: its matrices stay those of the last step (factors reused)
KEEP = 1.2


def predictor(old: Sequence[np.ndarray], k: Sequence[float]) -> np.ndarray:
    """x^p at tⁿ⁺¹ from xⁿ, xⁿ⁻¹, xⁿ⁻² (``old``, newest first) and the steps kₙ, kₙ₋₁, kₙ₋₂ (``k``)."""
    d_now = (old[0] - old[1]) / k[1]
    d_before = (old[1] - old[2]) / k[2]
    return old[0] + k[0] * (d_now + (k[0] + k[1]) / (k[1] + k[2]) * (d_now - d_before))


def local_error(new: np.ndarray, old: Sequence[np.ndarray], k: Sequence[float], scheme: TimeScheme) -> np.ndarray:
    """The local error of ``scheme``'s x^{n+1} = ``new`` from the old levels ``old`` on the steps ``k`` (module
    docstring): the scheme's Milne factor times x^{n+1} − x^p."""
    return scheme.milne(k) * (new - predictor(old, k))


@attrs.frozen
class Controller:
    """Gustafsson's PI step-size controller on the normalized error err (accept when err ≤ 1).

    >>> c = Controller()
    >>> c.accepted(0.1, 1.0)[0] > 1.0, c.accepted(1.0, 1.0)[0] < 1.0, c.rejected(4.0) < 1.0
    (True, True, True)
    >>> c.accepted(0.7, 1.0, held=1.18)       # a factor in [1, KEEP): keep the step
    (1.0, 1.0)
    >>> h = Controller(3, hold=True)
    >>> [round(x, 3) for x in h.accepted(0.1, 0.1)]     # ... and hold its growth back
    [1.0, 1.133]
    >>> [round(x, 3) for x in h.accepted(0.1, 0.1, held=1.133)]      # until the growth held reaches KEEP
    [1.284, 1.0]
    """

    order: int = 2
    hold: bool = False  #: a growth below KEEP is held back (True) or dropped (False)

    def factor(self, err: float, err_prev: float) -> float:
        """The PI factor SAFETY·err^(−KI/q)·err_prev^(KP/q), bounded to [SHRINK, GROW]: at a steady err it is
        SAFETY·err^(−(KI−KP)/q), 1 at err = SAFETY^(q/(KI−KP)) (0.50 for q = 2, 0.35 for q = 3, 0.70 for q = 1)."""
        err, err_prev = max(err, 1e-10), max(err_prev, 1e-10)
        return min(GROW, max(SHRINK, SAFETY * err ** (-KI / self.order) * err_prev ** (KP / self.order)))

    def kept(self, factor: float, held: float = 1.0) -> tuple[float, float]:
        """(the next step over this one, the growth held back) for the proposed ``factor``.

        A factor in [1, KEEP) keeps Δt. With ``hold`` its growth is held back, not dropped: the factors of the
        steps kept at one Δt multiply until they reach KEEP. Dropped, they can hold a PI controller, whose factor
        at a steady err is SAFETY·err^(−(KI−KP)/q) (1.13 at err = 0.1, q = 3), at one Δt with err far below 1.
        """
        if factor < 1.0:
            return factor, 1.0
        total = min(GROW, held * factor) if self.hold else factor
        if total < KEEP:
            return 1.0, total if self.hold else 1.0
        return total, 1.0

    def accepted(self, err: float, err_prev: float, held: float = 1.0) -> tuple[float, float]:
        """(the next step over this one, the growth held back) after an accepted step of error ``err`` (the one
        before: ``err_prev``), ``held`` the growth held back so far (:meth:`factor`, :meth:`kept`)."""
        return self.kept(self.factor(err, err_prev), held)

    def rejected(self, err: float) -> float:
        """The retried step over the rejected one (< 1)."""
        return min(SAFETY, max(REJECT_MIN, SAFETY * err ** (-1.0 / self.order)))
