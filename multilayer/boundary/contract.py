"""The boundary-condition contract: what an open end of the fluid (inlet, outlet) imposes.

The fluid asks each end's condition, every step, for the end's mean normal
stress as an affine function of the flux through it,

    p̄ = pressure + resistance · Q̄,

where Q̄ is the **outward** flux through the end of the step's test-level
velocity ū, measured by the geometry (∫ ū·n dA: cm²/s per unit depth in a
planar channel, cm³/s in a tube).  A prescribed pressure has no resistance;
a resistance or a Windkessel outlet, whose pressure follows the flow, has
one, and the fluid then carries the term R (∫ q·n)(∫ ū·n) in its matrix:
implicit, no sub-iterations (docs/theory.md, "Boundary conditions").

A condition may instead prescribe the flux itself (a flow rate: it
declares ``constraint`` and gives the outward flux Q(t),
:meth:`BoundaryCondition.flux`).  Its mean pressure is then an unknown of
the step, a Lagrange multiplier λ the fluid appends to its system (one per
such end), with the constraint that the new level has the flux,
∫ u^{n+1}·n = Q(tⁿ⁺¹): on the test level, ∫ ū·n = Q̄ = β₀Q(tⁿ⁺¹) plus the
old levels' fluxes (``EndTraction.flux``).  Once solved, the end's traction
is p̄ = λ, and that resolved traction is what the condition's ``advance``
and ``ledger`` receive (docs/boundary-conditions.md, "A prescribed flow rate").

A condition may have its own state (a Windkessel's capacitor pressure): a
value the fluid keeps in its state, one per end, that the condition
advances from the step's flux (:meth:`BoundaryCondition.advance`) and whose
stored energy it reports (:meth:`BoundaryCondition.energy`).  The energy
the end exchanges with the fluid over a step, −Δt p̄ Q̄, it splits into
work put in by its sources, energy dissipated and the change of its stored
energy (:meth:`BoundaryCondition.ledger`); the runner's ledger takes them as
columns.  Couplers pass conditions through without knowing their kind.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import attrs


@attrs.frozen
class EndTraction:
    """What an end imposes over one step: p̄ = ``pressure`` + ``resistance`` · Q̄ (Q̄ outward), or Q̄ = ``flux``.

    ``pressure`` in dyn/cm²; ``resistance`` in dyn·s/cm⁵ in a tube (dyn·s/cm⁴
    per unit depth in a planar channel), ≥ 0 for a dissipative end.
    """

    pressure: float
    resistance: float = 0.0
    #: the outward flux Q̄ of the step's test-level velocity (cm²/s per unit depth planar, cm³/s in a tube),
    #: for an end that prescribes it (:attr:`BoundaryCondition.constraint`; the fluid sets it from
    #: :meth:`BoundaryCondition.flux`); None: the flux is free.  Its pressure is then the multiplier λ once
    #: the step is solved (0 before)
    flux: float | None = None

    def mean(self, flux: float) -> float:
        """p̄ for the outward flux ``flux``."""
        return self.pressure + self.resistance * flux


@attrs.frozen
class BuildContext:
    """What a condition's factory may need beyond its parameters (``BoundaryPlugin(context=True)``).

    ``path`` is the key path of the end in the case file (``loads.inlet``),
    for messages; ``spec`` the end's value as the case writes it (a number,
    a string or a table); ``base_dir`` the folder relative file names are
    read from; ``constants`` the symbols a formula may use (L, R, H); ``end``
    the run's end time (s), over which a function of t must be finite.
    """

    path: str
    spec: Any = None
    base_dir: str = "."
    constants: Mapping[str, float] = attrs.field(factory=dict)
    end: float = 1.0


class BoundaryCondition(ABC):
    """The condition on one open end of the fluid.

    Subclass it, give :meth:`traction` (and, for a condition with memory,
    :meth:`initial_state`, :meth:`advance`, :meth:`energy`), and register it
    as a boundary plugin (``multilayer_boundaries``); a case chooses it as
    ``[loads] outlet = {model = "my-condition", ...}``.
    """

    #: True when the end's pressure may depend on its flux (a resistance): the fluid's system then holds
    #: the end's rank-one term, so its sparsity pattern couples the end's DOFs
    implicit: ClassVar[bool] = False
    #: True when the end prescribes its flux (:meth:`flux`) rather than its pressure: the fluid's system gains
    #: one unknown, the end's mean pressure λ, and the row ∫ J ū·n = Q̄ (in the sparsity pattern from setup);
    #: its :meth:`traction` has no pressure of its own (``EndTraction(0.0)``), and ``advance`` and ``ledger``
    #: receive the traction with pressure λ
    constraint: ClassVar[bool] = False

    def initial_state(self) -> Any:
        """The condition's own state at t = 0 (None: it has none)."""
        return None

    def state_to_data(self, state: Any) -> Any:
        """The condition's ``state`` as data a checkpoint can hold (numbers, arrays, strings, None, lists,
        tuples, mappings: no objects).  By default a state that is None or a number is itself; a
        condition with another kind of state gives its own (and :meth:`state_from_data`)."""
        if state is None:
            return None
        if isinstance(state, (int, float)) and not isinstance(state, bool):  # numpy's float64 too
            return float(state)
        raise NotImplementedError(f"{type(self).__name__} gives no state_to_data for its state "
                                  f"{type(state).__name__}: its runs cannot be checkpointed")

    def state_from_data(self, data: Any) -> Any:
        """The state :meth:`state_to_data` gave ``data`` for (ValueError for anything else).  By default
        None or a number (a flow rate's end: None at rest, then its multiplier λ)."""
        if data is None or isinstance(data, float):
            return data
        raise ValueError(f"{type(self).__name__}'s state should be None or a number, not {type(data).__name__}")

    @abstractmethod
    def traction(self, window: tuple[float, float], dt: float, scheme: Any, history: Sequence[Any]) -> EndTraction:
        """p̄ of the step as pressure + resistance · Q̄ (a ``constraint`` end: ``EndTraction(0.0)``, p̄ = λ).

        ``window`` is the interval the scheme averages loads over
        (:meth:`TimeScheme.load_window`: the step [tⁿ, tⁿ⁺¹] for backward Euler
        and Crank–Nicolson, one step centred on tⁿ⁺¹ for BDF2); ``history`` the condition's states
        at tⁿ, tⁿ⁻¹, ... (newest first), for a condition discretized by the
        step's time ``scheme`` (:class:`multilayer.numerics.timescheme.TimeScheme`).
        """

    def flux(self, time: float, history: Sequence[Any]) -> float:
        """The outward flux Q(t) a ``constraint`` end prescribes at ``time`` (the step's new level tⁿ⁺¹).

        The fluid imposes it on the new level's velocity, ∫ J u^{n+1}·n = Q(tⁿ⁺¹): a flux is
        data on the velocity, like a Dirichlet value, not a load averaged over the step.
        """
        raise NotImplementedError(f"{type(self).__name__} declares constraint = True but gives no flux")

    def advance(self, traction: EndTraction, flux: float, dt: float, scheme: Any, history: Sequence[Any]) -> Any:
        """The state at tⁿ⁺¹ from the step's outward flux Q̄ (a condition without state: None).

        For a ``constraint`` end, ``traction.pressure`` is the step's multiplier λ, its mean pressure.
        """
        return None

    def energy(self, end: str, state: Any) -> dict[str, float]:
        """Energy stored in the condition in ``state``, by ledger column (none by default)."""
        return {}

    def ledger(self, end: str, traction: EndTraction, flux: float, dt: float, old: Any, new: Any
               ) -> tuple[dict[str, float], dict[str, float]]:
        """(work, dissipation) of the end over the step, by ledger column.

        They satisfy work − dissipation − (stored(new) − stored(old)) = −Δt p̄ Q̄,
        the power the fluid receives through the end.  By default the
        pressure does work −Δt·pressure·Q̄ (column ``work.<end>``) and the
        resistance dissipates Δt·R·Q̄² (``dissipation.<end>.resistance``).
        """
        work = {f"work.{end}": -dt * traction.pressure * flux}
        if traction.resistance == 0.0:
            return work, {}
        return work, {f"dissipation.{end}.resistance": dt * traction.resistance * flux * flux}

    def columns(self, end: str, state: Any) -> dict[str, float]:
        """Values of the condition's own state to write in ``series.csv`` (e.g. a capacitor's pressure,
        ``end.<end>.P_c``); the fluid writes each end's flux and mean pressure (``end.<end>.Q``, ``.p``)."""
        return {}

    def at_rest(self) -> bool:
        """True when the end imposes nothing at all (p ≡ 0, no resistance): a coupler that applies no end
        loads accepts it."""
        return False

    def histories(self) -> tuple[Any, ...]:
        """The functions of t the end prescribes (:class:`multilayer.functions.loads.PressureLoad` each: a
        pressure, a flow rate); none by default.  Adaptive steps land on their breakpoints and take their
        shortest period as the memory time (``time.memory``)."""
        return ()

    def resolved(self) -> dict[str, Any] | None:
        """The condition as case-file data with defaults filled, when it is more than its kind and
        parameters (e.g. a table's SHA-256); None: its kind and parameters say it all."""
        return None
