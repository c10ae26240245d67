"""The coupler contract: a time-stepping scheme as a pure stepper over a frozen setup."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, ClassVar

import attrs

from multilayer.functions.loads import is_zero
from multilayer.numerics.timescheme import SCHEMES, TimeScheme

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
    balances the lumen's volume in that form (theory §7, "Volume").
    """

    stored: Mapping[str, float] = attrs.field(factory=dict)
    work: Mapping[str, float] = attrs.field(factory=dict)
    dissipation: Mapping[str, float] = attrs.field(factory=dict)
    diagnostics: Mapping[str, float] = attrs.field(factory=dict)
    alpha: tuple[float, ...] = (1.0, -1.0)


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
    #: the time schemes (:data:`multilayer.numerics.timescheme.SCHEMES`) it offers; its ``scheme`` parameter
    schemes: ClassVar[tuple[str, ...]] = ("backward-euler",)
    #: the schemes with which it takes adaptive steps (``[time] tolerance``): those it has an error estimate for
    adaptive: ClassVar[tuple[str, ...]] = ()

    def __init__(self, scheme: str = "backward-euler"):
        if scheme not in self.schemes:
            raise ValueError(f"scheme {scheme!r} is not offered; choose one of {', '.join(self.schemes)}")
        self.scheme: TimeScheme = SCHEMES[scheme]

    def check_case(self, case: Case) -> list[str]:
        """Reasons this coupler cannot run ``case`` (empty when it can).

        Called by the case validator, so ``multilayer validate`` reports them.
        The default rejects a non-zero load that the coupler would ignore.
        """
        name = getattr(self, "name", type(self).__name__)
        def set_(key):
            load = getattr(case.loads, key)
            return not load.at_rest() if key in ("inlet", "outlet") else not is_zero(load)

        return [f"loads.{key} is set, but {name} does not apply it (it applies: {', '.join(self.loads) or 'none'})"
                for key in ("inlet", "outlet", "external", "interface") if key not in self.loads and set_(key)
                ] + self.adaptive_problems(case)

    def adaptive_problems(self, case: Case) -> list[str]:
        """Why ``case``'s adaptive steps (``time.tolerance``) cannot be taken: no error estimate for the scheme."""
        if case.time.tolerance is None or self.scheme.name in self.adaptive:
            return []
        name = getattr(self, "name", type(self).__name__)
        offered = (f"it takes them with scheme = {' or '.join(repr(s) for s in self.adaptive)}" if self.adaptive
                   else "choose 'monolithic' with scheme = 'crank-nicolson' or 'bdf2', or 'kinematic-splitting' "
                        "with scheme = 'crank-nicolson'")
        why = "first order" if self.scheme.order == 1 else f"not estimated in {name}"
        reason = (f"time.tolerance = {case.time.tolerance:g} asks for adaptive steps, which {name} with scheme "
                  f"{self.scheme.name!r} does not take (no error estimate: {self.scheme.name} is {why}); "
                  f"{offered}, or remove time.tolerance")
        return [reason]

    def energy_bound_note(self, case: Case) -> str:
        """What the runner adds when a step breaks E ≤ E⁰ + work beyond ``solver.energy_margin`` (empty: nothing).

        Variable-step BDF2 is not G-stable for growing steps: its energy may exceed E⁰ + work by a few percent
        without any instability (docs/theory.md, "Variable-step BDF2").
        """
        if case.time.tolerance is None or self.scheme.levels <= 2:
            return ""
        return (f" — or not: with adaptive steps, {self.scheme.name}'s energy may exceed E⁰ + work by a few percent "
                f"of the work while the steps grow, without instability (its G-norm depends on the step ratio: "
                f"docs/theory.md, 'Variable-step BDF2'); set solver.energy_margin = 0.05")


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
