"""Steps chosen by error: the local error estimates of Crank–Nicolson and BDF2, and the step-size controller.

The estimate (derivation in docs/theory.md, "Adaptive steps") compares the
corrector's value x^{n+1} with an explicit AB2-type predictor built from
levels the run already has: the midpoint difference quotients
Dⁿ = (xⁿ − xⁿ⁻¹)/kₙ₋₁ and Dⁿ⁻¹ = (xⁿ⁻¹ − xⁿ⁻²)/kₙ₋₂ stand at tⁿ⁻½ and tⁿ⁻³ᐟ²;
extrapolated linearly to tⁿ⁺½ they give

    x^p = xⁿ + kₙ (Dⁿ + (kₙ + kₙ₋₁)/(kₙ₋₁ + kₙ₋₂) (Dⁿ − Dⁿ⁻¹)),

exact for quadratics (AB2 with midpoint slopes; it is the quadratic through
xⁿ⁻², xⁿ⁻¹, xⁿ evaluated at tⁿ⁺¹).  Its error is, to leading order,

    x(tⁿ⁺¹) − x^p = kₙ(kₙ + kₙ₋₁)(kₙ + kₙ₋₁ + kₙ₋₂)/6 x''',

and the correctors' local errors are

    Crank–Nicolson:  x^{n+1} − x(tⁿ⁺¹) = kₙ³/12 x''',
    BDF2:            x^{n+1} − x(tⁿ⁺¹) = kₙ²(kₙ + kₙ₋₁)/(6α₀) x''',   α₀ = (1 + 2ω)/(1 + ω), ω = kₙ/kₙ₋₁,

so the local error is the computed difference scaled (Milne's device, :func:`milne`):

    Crank–Nicolson:  e = kₙ² / (kₙ² + 2(kₙ + kₙ₋₁)(kₙ + kₙ₋₁ + kₙ₋₂)) · (x^{n+1} − x^p)   (1/13 for equal steps),
    BDF2:            e = kₙ / (kₙ + α₀(kₙ + kₙ₋₁ + kₙ₋₂)) · (x^{n+1} − x^p)               (2/11 for equal steps).

No linear solve: the predictor is three old levels.

>>> k = [0.1, 0.1, 0.1]
>>> t = np.array([0.3, 0.2, 0.1, 0.0])
>>> xs = [t[i] ** 3 / 6 for i in range(4)]          # x''' = 1
>>> cn = xs[0] + k[0] ** 3 / 12                       # the CN value: exact + its local error
>>> round(float(local_error(cn, xs[1:], k) / (k[0] ** 3 / 12)), 12)
1.0
>>> round(milne("crank-nicolson", k), 12), round(milne("bdf2", k), 12)
(0.076923076923, 0.181818181818)
"""

from __future__ import annotations

from collections.abc import Sequence

import attrs
import numpy as np

from multilayer.numerics.timescheme import bdf2_alpha

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


def bdf2_alpha0(k: Sequence[float]) -> float:
    """Variable-step BDF2's α₀ = (1 + 2ω)/(1 + ω) (:func:`~multilayer.numerics.timescheme.bdf2_alpha`) for the
    steps k = [kₙ, kₙ₋₁, ...], ω = kₙ/kₙ₋₁."""
    return bdf2_alpha(k[0] / k[1])[0]


def milne(scheme: str, k: Sequence[float]) -> float:
    """e/(x^{n+1} − x^p): ``scheme``'s local error of x^{n+1} over its distance from the predictor (module docstring).

    >>> round(milne("bdf2", [0.2, 0.1, 0.1]), 12)        # ω = 2, α₀ = 5/3: 0.2/(0.2 + 5/3 · 0.4) = 3/13
    0.230769230769
    """
    if scheme == "crank-nicolson":
        return k[0] ** 2 / (k[0] ** 2 + 2.0 * (k[0] + k[1]) * (k[0] + k[1] + k[2]))
    if scheme == "bdf2":
        return k[0] / (k[0] + bdf2_alpha0(k) * (k[0] + k[1] + k[2]))
    raise ValueError(f"no local error estimate for {scheme!r}; there is one for crank-nicolson and bdf2")


def carried(scheme: str, k: Sequence[float]) -> float:
    """How much of a step's local error stays in the run's (smooth) error: 1 for a one-step rule, α₀ for BDF2.

    BDF2's error recursion α₀(eⁿ⁺¹ − eⁿ) − α₂(eⁿ − eⁿ⁻¹) = kₙτ + …, for a smooth error
    (eⁿ − eⁿ⁻¹ ≈ (eⁿ⁺¹ − eⁿ)/ω), is (α₀ − α₂/ω)(eⁿ⁺¹ − eⁿ) = eⁿ⁺¹ − eⁿ = kₙτ: a step adds its
    truncation error kₙτ = α₀ · (its local error), not the local error itself (docs/theory.md, "Adaptive steps").

    >>> carried("crank-nicolson", [0.1, 0.1, 0.1]), carried("bdf2", [0.1, 0.1, 0.1])
    (1.0, 1.5)
    """
    return bdf2_alpha0(k) if scheme == "bdf2" else 1.0


def local_error(new: np.ndarray, old: Sequence[np.ndarray], k: Sequence[float],
                scheme: str = "crank-nicolson") -> np.ndarray:
    """The local error of ``scheme``'s x^{n+1} = ``new`` (module docstring)."""
    return milne(scheme, k) * (new - predictor(old, k))


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
