"""Time schemes: the contract a time-scheme plugin implements, and the linear multistep rule its stages follow.

A time scheme is a plugin (``multilayer_schemes``, :class:`~multilayer.plugin.records.SchemePlugin`):
one module per scheme, ``multilayer_plugins/schemes/`` for the built-in ones, each a subclass of
:class:`TimeScheme`.  The core and the couplers ask a scheme for what they need — its weights, its
energy identity, its error estimate, where its geometry sits — and never for its name.

A step is a sequence of **stages** (:attr:`TimeScheme.stages`); each is a single-stage scheme, a linear
multistep rule with coefficients α (the difference quotient) and β (where the operator is evaluated), levels
newest first:

    Σ_k α_k x^{n+1−k} / Δt · M  +  A x̄  =  F̄,      x̄ = Σ_k β_k x^{n+1−k}.

Backward Euler, Crank–Nicolson and BDF2 are single-stage: the scheme is its own stage.  A multi-stage
scheme (TR-BDF2) lists its stages, each a single-stage scheme over its own sub-step, and the clock steps
them one after the other (:func:`multilayer.coupling.clock.march`): a coupler only ever steps a
single-stage rule.  Every
sub-problem of the project (a wall step, a fluid step, both at once) is solved for the *test-level*
unknown x̄: the matrix is (α₀/β₀) M/Δt + A and only old levels move to the right-hand side.  For
Crank–Nicolson x̄ is the midpoint value and the step is a backward-Euler step of Δt/2 followed by the
extrapolation x^{n+1} = 2x̄ − xⁿ (the refactorized midpoint rule); for backward Euler and BDF2, x̄ = x^{n+1}.

Testing with x̄ gives the energy identity of the scheme, for q(x) = ½xᵀMx:

    (Σ_k α_k x^{n+1−k})ᵀ M x̄ = stored(q, xⁿ⁺¹…) − before(q, xⁿ⁺¹…) + numerical(q, xⁿ⁺¹…)

where ``stored`` is the energy the scheme carries at the new level, ``before`` the same at the old level
as the step before stored it, and ``numerical`` the numerical dissipation.  Each scheme states its own
(the built-in ones: docs/theory.md §4); every registered scheme is checked against this identity on
random vectors (``tests/test_timescheme.py``).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from typing import Any, ClassVar

import attrs
import numpy as np

from multilayer.plugin.records import MODEL, Param
from multilayer.plugin.registry import Registry

Quadratic = Callable[[np.ndarray], float]


class LinearMultistep:
    """The rule Σα_k x^{n+1−k}/Δt·M + A x̄ = F̄, x̄ = Σβ_k x^{n+1−k}, from its ``alpha`` and ``beta`` (levels newest
    first): what a stage, and a single-stage scheme, computes with its weights."""

    alpha: tuple[float, ...]
    beta: tuple[float, ...]

    @property
    def levels(self) -> int:
        """Time levels the rule involves, the new one included."""
        return len(self.alpha)

    @property
    def inertia(self) -> float:
        """α₀/β₀: the matrix of the step is inertia·M/Δt + A.  Δt/inertia is the step of the
        equivalent backward-Euler solve (Δt/2 for Crank–Nicolson)."""
        return self.alpha[0] / self.beta[0]

    @property
    def theta(self) -> float:
        """Where the operator is evaluated, as a fraction of the step: t = tⁿ + θΔt (θ = Σβ_k(1 − k))."""
        return float(sum(b * (1 - k) for k, b in enumerate(self.beta)))

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


@attrs.frozen
class Stage:
    """One stage of a step: a single-stage scheme stepped over a sub-step that ends at tⁿ + ``fraction``·Δt.

    The stage starts where the stage before it ended (tⁿ for the first) and is stepped as any single-stage
    scheme is, with its sub-step's Δt; its levels are read along the chain of states, newest first: its own
    new value, the values of the step's earlier stages (latest first), then the step's old levels xⁿ,
    x^{n−1}, ...  Its ``ratio`` is its sub-step over the distance between its two newest old levels (that is
    what its extrapolations see).  A single-stage scheme has one stage, itself, with ``fraction`` = 1.

    >>> class Euler(TimeScheme):  # a stand-in single-stage scheme (the built-in ones: multilayer_plugins/schemes)
    ...     name, alpha, beta = "euler", (1.0, -1.0), (1.0, 0.0)
    >>> [(s.scheme.name, s.fraction) for s in Euler().stages]
    [('euler', 1.0)]
    """

    scheme: TimeScheme
    fraction: float = 1.0


@attrs.frozen
class TimeScheme(LinearMultistep):
    """A time scheme, as a plugin implements it (subclass it; see the module docstring).

    A single-stage scheme defines :attr:`alpha` and :attr:`beta` (as properties, or attributes), the
    class attributes :attr:`name` and :attr:`order`, its energy identity (:meth:`stored`,
    :meth:`numerical`; :meth:`before` follows) and its :meth:`geometry`; everything else has a default
    a scheme may override: its error estimate for adaptive steps (:meth:`milne`, :meth:`carried`,
    :attr:`estimates_error`), what a change of step size means to it (:meth:`with_ratio`,
    :attr:`max_ratio`), its load window and extrapolation.  A subclass's own fields are its
    parameters (:attr:`parameters`); ``ratio`` and ``previous`` are the step's.

    A multi-stage scheme defines :attr:`stages` instead (single-stage schemes, each over its sub-step),
    its :meth:`stored` (the energy its last stage stores, which the next step's first stage starts
    from), ``alpha`` = (1, −1) (the step as a whole takes xⁿ to x^{n+1}: one-step) and its error
    estimate; the couplers step its stages, never the scheme itself.

    Parameters
    ----------
    ratio : float
        ω = Δtⁿ/Δtⁿ⁻¹, the step's ratio to the one before (1 for constant steps): the
        extrapolations see it, and a variable-step multistep rule's α (:meth:`with_ratio`).
    previous : float
        The ratio of the step before (a G-norm of the old level may be that step's).
    """

    ratio: float = attrs.field(default=1.0, kw_only=True)
    previous: float = attrs.field(default=1.0, kw_only=True)

    #: the name a case file uses (``coupler.scheme``), the plugin record's
    name: ClassVar[str] = "time-scheme"
    #: order of accuracy in time
    order: ClassVar[int] = 1
    #: True when :meth:`milne` estimates the local error (adaptive steps, ``[time] tolerance``)
    estimates_error: ClassVar[bool] = False
    #: True when the scheme carries stiff modes undamped, as an alternating (−1)ⁿ mode (amplification −1 as
    #: ωΔt → ∞): the clock then drops that mode's echo from its error estimate (:func:`multilayer.coupling.clock.unechoed`)
    undamped: ClassVar[bool] = False
    #: what the runner adds when a run with adaptive steps breaks E ≤ E⁰ + work (empty: nothing): a scheme whose
    #: stored energy depends on the step ratio may exceed it without instability
    adaptive_energy_note: ClassVar[str] = ""

    @property
    def beta(self) -> tuple[float, ...]:
        """A single-stage scheme's β (it defines its own); a multi-stage scheme has none, its stages do:

        >>> class Split(TimeScheme):  # a stand-in scheme of two stages
        ...     name = "split"
        ...     stages = property(lambda self: (Stage(self, 0.5), Stage(self, 1.0)))
        >>> Split().beta
        Traceback (most recent call last):
        ...
        AttributeError: split takes 2 stages a step: step each stage, a single-stage scheme (TimeScheme.substeps)
        """
        raise AttributeError(f"{self.name} takes {len(self.stages)} stages a step: step each stage, a single-stage "
                             f"scheme (TimeScheme.substeps)")

    # -- the step's stages -----------------------------------------------------------
    @property
    def stages(self) -> tuple[Stage, ...]:
        """The stages of one step, in order (:class:`Stage`): one, the scheme itself, for a single-stage scheme.

        A multi-stage scheme overrides this; its stages are single-stage schemes, each with its own identity
        (their stored energies chain: a stage's ``before`` is what the stage before it stored), and the
        scheme's own :meth:`stored` is its last stage's, which the next step's first stage starts from.
        """
        return (Stage(self, 1.0),)

    def substeps(self, t0: float, t1: float, dt: float | None = None) -> list[tuple[TimeScheme, float, float, float]]:
        """(stage scheme, its start, its end, its Δt) of each stage of the step [t0, t1] of Δt = ``dt`` (t1 − t0
        by default), in order: the last ends at t1, a stage's Δt is its share of the step's, Δt itself for a
        single stage (so that a matrix held per Δt is the same at every step).

        >>> class Euler(TimeScheme):  # stand-ins: a single-stage scheme, and two of its stages a step
        ...     name, alpha, beta = "euler", (1.0, -1.0), (1.0, 0.0)
        >>> class Split(TimeScheme):
        ...     name = "split"
        ...     stages = property(lambda self: (Stage(Euler(), 0.5), Stage(Euler(), 1.0)))
        >>> Euler().substeps(0.0, 0.1)
        [(Euler(ratio=1.0, previous=1.0), 0.0, 0.1, 0.1)]
        >>> [(start, end, dt) for _, start, end, dt in Split().substeps(0.0, 0.1)]
        [(0.0, 0.05, 0.05), (0.05, 0.1, 0.05)]
        """
        dt = t1 - t0 if dt is None else dt
        out, start, done = [], t0, 0.0
        for stage in self.stages:
            end = t1 if stage.fraction == 1.0 else t0 + stage.fraction * (t1 - t0)
            out.append((stage.scheme, start, end, dt if done == 0.0 and stage.fraction == 1.0
                        else (stage.fraction - done) * dt))
            start, done = end, stage.fraction
        return out

    @property
    def parameters(self) -> dict[str, Any]:
        """The scheme's own parameters (its fields but the step's ratios), for the run's summary."""
        return {f.name: getattr(self, f.name) for f in attrs.fields(type(self)) if f.name not in ("ratio", "previous")}

    # -- a change of step size --------------------------------------------------------
    def with_ratio(self, ratio: float, previous: float = 1.0) -> TimeScheme:
        """This scheme for a step ω = ``ratio`` times the one before, which was ``previous`` times its own.

        A one-step rule keeps its coefficients (its identity holds step by step with that step's Δt); a
        variable-step multistep rule overrides this (its α depends on ω).
        """
        return attrs.evolve(self, ratio=float(ratio), previous=float(previous))

    @property
    def max_ratio(self) -> float:
        """The largest step ratio ω the scheme takes (zero stability): none for a one-step rule."""
        return math.inf

    @property
    def old_levels(self) -> int:
        """Old levels a step needs: the rule's, and two for a second-order scheme's extrapolations."""
        return max(len(self.alpha) - 1, self.order)

    # -- explicit parts: extrapolation, geometry, loads ------------------------------------
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
        """The wall displacement a fluid step is assembled on, from η^{n+1}, ηⁿ, ... (newest first)."""
        raise NotImplementedError(f"time scheme {self.name!r} does not say where its geometry is (geometry)")

    @property
    def geometry_position(self) -> float:
        """Where the domain of :meth:`geometry` sits in the step, as a fraction: tⁿ + position·Δt."""
        return float(self.geometry([np.ones(1), *[np.zeros(1)] * max(2, self.levels - 1)])[0])

    def load_window(self, t0: float, t1: float) -> tuple[float, float]:
        """The time window whose average load is F̄: [tⁿ, tⁿ⁺¹] for a first-order scheme; else one step centred
        where the operator is evaluated, tⁿ + θΔt."""
        if self.order == 1:
            return t0, t1
        centre = t0 + self.theta * (t1 - t0)
        half = 0.5 * (t1 - t0)
        return centre - half, centre + half

    # -- the energy identity -------------------------------------------------------------
    def stored(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        """The energy the scheme's identity carries at the newest level of ``xs`` (newest first)."""
        raise NotImplementedError(f"time scheme {self.name!r} has no energy identity (stored)")

    def before(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        """The energy at the old level xⁿ of ``xs`` (newest first) as the step before stored it (its ratio)."""
        if self.previous == self.ratio:
            return self.stored(q, xs[1:])
        return attrs.evolve(self, ratio=self.previous).stored(q, xs[1:])

    def numerical(self, q: Quadratic, xs: Sequence[np.ndarray]) -> float:
        """Numerical dissipation of one step: Σα_k x^{n+1−k}·M x̄ − stored + before."""
        raise NotImplementedError(f"time scheme {self.name!r} has no energy identity (numerical)")

    # -- the error estimate of adaptive steps ------------------------------------------------
    def milne(self, k: Sequence[float]) -> float:
        """e/(x^{n+1} − x^p): the local error of x^{n+1} over its distance from the clock's predictor
        (:func:`multilayer.numerics.stepsize.predictor`) on the steps k = [kₙ, kₙ₋₁, kₙ₋₂] (Milne's device);
        only for a scheme with :attr:`estimates_error`."""
        raise ValueError(f"no local error estimate for {self.name!r}")

    def carried(self, k: Sequence[float]) -> float:
        """How much of a step's local error stays in the run's (smooth) error: 1 for a one-step rule."""
        return 1.0


def scheme_param(default: str = "backward-euler") -> Param:
    """The ``scheme`` parameter of a coupler: the name of a registered time scheme (or a table with its parameters)."""
    return Param("scheme", type=str, default=default, plugin="scheme",
                 doc="time discretization: a registered time scheme ('multilayer plugins' lists them), by name, "
                     "or as a table {model = name, ...its parameters}")


@functools.cache
def _installed() -> Registry:
    """The installed plugins, loaded once, when first asked for."""
    return Registry.load()


def named(name: str, registry: Registry | None = None, **params: Any) -> TimeScheme:
    """The registered time scheme ``name`` built with ``params`` (the installed plugins by default).

    >>> from multilayer.plugin.hookspecs import hookimpl
    >>> from multilayer.plugin.records import SchemePlugin
    >>> class Euler(TimeScheme):  # a stand-in scheme, and a plugin that registers it
    ...     name, alpha, beta = "euler", (1.0, -1.0), (1.0, 0.0)
    >>> class Schemes:
    ...     @hookimpl
    ...     def multilayer_schemes(self):
    ...         return [SchemePlugin(name="euler", factory=Euler, doc="Backward Euler.")]
    >>> registry = Registry.load([Schemes()], entry_points=False)
    >>> named("euler", registry).levels, named("euler", registry, ratio=2.0).ratio
    (2, 2.0)
    """
    return (registry or _installed()).build("scheme", {MODEL: name, **params})


def schemes(registry: Registry | None = None) -> dict[str, TimeScheme]:
    """Every registered time scheme that takes its parameters' defaults, built, by name (the installed plugins
    by default).

    >>> from multilayer.plugin.hookspecs import hookimpl
    >>> from multilayer.plugin.records import Param, SchemePlugin
    >>> class Euler(TimeScheme):  # a stand-in scheme
    ...     name, alpha, beta = "euler", (1.0, -1.0), (1.0, 0.0)
    >>> class Schemes:  # a plugin of two schemes, one with a parameter to give
    ...     @hookimpl
    ...     def multilayer_schemes(self):
    ...         return [SchemePlugin(name="euler", factory=Euler, doc="Backward Euler."),
    ...                 SchemePlugin(name="theta", factory=Euler, params=(Param("theta", unit="1"),), doc="θ.")]
    >>> sorted(schemes(Registry.load([Schemes()], entry_points=False)))
    ['euler']
    """
    registry = registry or _installed()
    out = {}
    for name in registry.names("scheme"):
        record = registry.get("scheme", name).record
        if not any(p.required for p in record.params):
            out[name] = registry.build("scheme", name)
    return out


def stage_schemes(registry: Registry | None = None) -> dict[str, TimeScheme]:
    """The single-stage scheme of every stage of every registered scheme that takes its parameters' defaults
    (:func:`schemes`), by name: the scheme's own for a single-stage one, ``<name>[k]`` for a multi-stage one's
    stage k — what a test of one step's identity runs over.

    >>> from multilayer.plugin.hookspecs import hookimpl
    >>> from multilayer.plugin.records import SchemePlugin
    >>> class Euler(TimeScheme):  # stand-ins: a single-stage scheme, and two of its stages a step
    ...     name, alpha, beta = "euler", (1.0, -1.0), (1.0, 0.0)
    >>> class Split(TimeScheme):
    ...     name = "split"
    ...     stages = property(lambda self: (Stage(Euler(), 0.5), Stage(Euler(), 1.0)))
    >>> class Schemes:
    ...     @hookimpl
    ...     def multilayer_schemes(self):
    ...         return [SchemePlugin(name="euler", factory=Euler, doc="Backward Euler."),
    ...                 SchemePlugin(name="split", factory=Split, doc="Two stages.")]
    >>> sorted(stage_schemes(Registry.load([Schemes()], entry_points=False)))
    ['euler', 'split[0]', 'split[1]']
    """
    out = {}
    for name, scheme in schemes(registry).items():
        stages = scheme.stages
        out.update({name: scheme} if len(stages) == 1 else {f"{name}[{k}]": s.scheme for k, s in enumerate(stages)})
    return out


def levels(x: np.ndarray, history: Sequence[np.ndarray], n: int) -> list[np.ndarray]:
    """[x, history[0], ...] padded to ``n`` levels by repeating the oldest (rest before t = 0)."""
    out = [x, *history][:n]
    while len(out) < n:
        out.append(out[-1])
    return out
