"""The coupler contract: a time-stepping scheme as a pure stepper over a frozen setup."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, ClassVar

import attrs

from multilayer.functions.loads import is_zero
from multilayer.numerics.timescheme import TimeScheme, named

if TYPE_CHECKING:  # pragma: no cover

    from multilayer.case.model import Case
    from multilayer.scene.setup import Setup
    from multilayer.scene.state import State


@attrs.frozen
class StepReport:
    """The energy terms of one step (theory §7), by column name, as a coupler reports them.

    ``stored`` is the energy at tⁿ⁺¹ as the scheme's identity measures it
    (kinetic and elastic, per part), ``work`` what the loads put in,
    ``dissipation`` what viscosity, the scheme and the explicit geometry
    take out (a geometric remainder may be negative).  The runner closes
    the ledger from them: Eⁿ⁺¹ − Eⁿ − work + dissipation = 0.
    ``diagnostics`` are extra columns (e.g. each sub-step's own residual).
    ``alpha`` are the weights of the step's difference quotient,
    Σ α_k x^{n+1−k} = Δt x̄' (newest level first): the volume ledger
    balances the lumen's volume in that form (theory §7, "Volume"), stage by stage for a
    multi-stage scheme (``stages``).
    """

    stored: Mapping[str, float] = attrs.field(factory=dict)
    work: Mapping[str, float] = attrs.field(factory=dict)
    dissipation: Mapping[str, float] = attrs.field(factory=dict)
    diagnostics: Mapping[str, float] = attrs.field(factory=dict)
    alpha: tuple[float, ...] = (1.0, -1.0)
    #: a multi-stage scheme's step: each stage's new state and report, in order (empty for a single stage;
    #: :func:`multilayer.coupling.clock.merged`)
    stages: tuple[tuple[State, StepReport], ...] = ()

    def parts(self, new: State) -> tuple[tuple[State, StepReport], ...]:
        """(state, report) of each stage of the step that made ``new``: the step itself when it has one stage."""
        return self.stages or ((new, self),)


class SchemeFailure(Exception):
    """A coupler cannot go on (e.g. sub-iterations that do not converge); the message says where and when."""


class Coupler(ABC):
    """A time-stepping scheme: a pure stepper over a frozen setup.

    ``evolve(setup, state0)`` yields ``(state, report)`` after every step:
    the new :class:`~multilayer.scene.state.State` (a value; nothing is mutated)
    and the step's :class:`StepReport`.  The runner writes rows, probes
    and snapshots from them and closes the energy ledger.
    """

    #: the loads (keys of ``[loads]``) this coupler applies; any other must be left at 0
    loads: ClassVar[tuple[str, ...]] = ()
    #: True when it takes adaptive steps (``[time] tolerance``) with a scheme that estimates its local error
    #: (:attr:`~multilayer.numerics.timescheme.TimeScheme.estimates_error`): its steps go through
    #: :func:`multilayer.coupling.clock.march`
    adaptive: ClassVar[bool] = False
    #: True when its steps go through :func:`multilayer.coupling.clock.march`, which steps a multi-stage scheme
    #: (:attr:`~multilayer.numerics.timescheme.TimeScheme.stages`) stage by stage, each stage one single-stage
    #: step of the coupler's with the stage's scheme over its sub-step
    multistage: ClassVar[bool] = False

    def __init__(self, scheme: TimeScheme | str = "backward-euler"):
        #: the time scheme (a plugin): the case's ``coupler.scheme``, built (a name is looked up among the
        #: installed schemes)
        self.scheme: TimeScheme = scheme if isinstance(scheme, TimeScheme) else named(scheme)

    def scheme_problems(self, scheme: TimeScheme) -> list[str]:
        """Why this coupler cannot step with ``scheme`` (empty when it can), from the scheme's capabilities.

        The case validator reports each at ``coupler.scheme``, with the registered schemes the coupler
        does take.  A coupler steps one single-stage rule per step; a multi-stage scheme
        (:attr:`~multilayer.numerics.timescheme.TimeScheme.stages`) only when its steps go through the clock,
        which steps the stages (:attr:`multistage`).
        """
        stages = len(scheme.stages)
        if stages == 1 or self.multistage:
            return []
        name = getattr(self, "name", type(self).__name__)
        return [f"{scheme.name} has {stages} stages a step, and {name} steps one linear multistep stage a step"]

    def check_case(self, case: Case) -> list[str]:
        """Reasons this coupler cannot run ``case`` (empty when it can).

        Called by the case validator, so ``multilayer validate`` reports them.
        The default rejects a non-zero load that the coupler would ignore.
        (Whether it can step with its scheme, and take the case's adaptive steps with
        it, the validator asks :meth:`scheme_problems` and :attr:`adaptive`.)
        """
        name = getattr(self, "name", type(self).__name__)
        def set_(key):
            load = getattr(case.loads, key)
            return not load.at_rest() if key in ("inlet", "outlet") else not is_zero(load)

        return [f"loads.{key} is set, but {name} does not apply it (it applies: {', '.join(self.loads) or 'none'})"
                for key in ("inlet", "outlet", "external", "interface") if key not in self.loads and set_(key)]

    def energy_bound_note(self, case: Case) -> str:
        """What the runner adds when a step breaks E ≤ E⁰ + work beyond ``solver.energy_margin`` (empty: nothing).

        With adaptive steps, the scheme's own note
        (:attr:`~multilayer.numerics.timescheme.TimeScheme.adaptive_energy_note`): variable-step BDF2 is not
        G-stable for growing steps, and its energy may exceed E⁰ + work by a few percent without any instability.
        """
        if case.time.tolerance is None:
            return ""
        return self.scheme.adaptive_energy_note

    def fluid_wall(self, case: Case) -> str:
        """How the fluid sees the wall: ``coupled``, ``rigid`` or ``prescribed``."""
        return "coupled"

    def fluid_interface_block(self, case: Case) -> bool:
        """True when this coupler's interface terms couple every two DOFs of the fluid's wall line (a wall step
        condensed on Γ), so that the fluid's sparsity pattern holds that whole block."""
        return False

    def radial_lines(self, case: Case) -> tuple[int, ...]:
        """Interface lines whose axial displacement d_z this coupler holds at zero.

        Beyond those under a thin layer, which always are (a thin layer moves
        radially only): a coupler that glues a fluid radially to a thick band
        names the lumen line here (theory §1).
        """
        return ()

    def initial_state(self, setup: Setup) -> State:
        """The state at t = 0 (the case's initial wall, the fluid at rest)."""
        return setup.initial_state()

    @abstractmethod
    def energy(self, setup: Setup, state: State) -> dict[str, float]:
        """The stored energy of ``state`` by part, as this scheme's identity measures it."""

    @abstractmethod
    def evolve(self, setup: Setup, state: State) -> Iterator[tuple[State, StepReport]]:
        """Advance from ``state`` step by step, yielding the new state and the step's report."""
