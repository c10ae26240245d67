"""The steps of a run: the coupler advances, the ledger closes, the guards check, the probes read.

:func:`iterate_steps` is the one place where a step happens.  The run loop
(:mod:`multilayer.runner.loop`) consumes it and adds the results folder,
snapshots, checkpoints, signals and the summary; the Python API
(:mod:`multilayer.api`) consumes it to run in memory or to hand the steps
to the caller.  Per step, in this order:

1. the coupler advances the state (``coupler.evolve``);
2. the energy ledger closes (:func:`multilayer.runner.ledger.close`), and
   with a fluid the volume ledger (:class:`multilayer.runner.volume.VolumeLedger`);
3. the state is checked (:func:`check_state`: non-finite values, a wall
   collapsing or blown out) — a failure here keeps no row of the step;
4. the probes are evaluated and the step's row is handed to the output;
5. the tally counts the step (steps, time, largest residual, peak |η|) and
   the output writes its fields (snapshots when due);
6. the energy bound (:class:`EnergyBound`) and the volume margin are
   checked — after the row is written, so the row that breaks them is kept;
7. the :class:`Step` is yielded.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Iterator, Mapping
from typing import Any, Protocol

import attrs
import numpy as np

from multilayer.coupling.contract import Coupler
from multilayer.runner import ledger
from multilayer.runner.volume import LumenVolume, VolumeLedger
from multilayer.scene.setup import Setup
from multilayer.scene.state import State


class RunFailed(Exception):
    """The run cannot go on; the message says where and when."""


def check_state(setup: Setup, state: State, row: dict[str, float]) -> None:
    """Stop on a non-finite value, a wall collapsing onto the axis (R + η ≤ 0) or one blown outward.

    Outward means |η| on the lumen beyond ``[solver] max_displacement`` × R.
    """
    t = state.t
    bad = [k for k, v in row.items() if not math.isfinite(v)]
    if bad:
        raise RunFailed(f"non-finite value at t = {t:.6g} s in {', '.join(sorted(bad)[:5])}")
    if state.wall is not None:
        for name, vec in (("wall displacement", state.wall.d), ("wall velocity", state.wall.V)):
            if not np.all(np.isfinite(vec)):
                raise RunFailed(f"non-finite {name} at t = {t:.6g} s")
        gap = setup.case.geometry.radius + setup.eta(state, 0)
        if np.min(gap) <= 0.0:
            i = int(np.argmin(gap))
            z = setup.wall.lines[0].z[i]
            raise RunFailed(f"wall collapse at t = {t:.6g} s, z = {z:.6g} cm: R + η = {gap[i]:.6g} cm ≤ 0")
        limit = setup.case.limits.max_displacement * setup.case.geometry.radius
        eta = gap - setup.case.geometry.radius
        i = int(np.argmax(np.abs(eta)))
        if abs(eta[i]) > limit:
            how = "blow-out (outward)" if eta[i] > 0 else "collapse (inward)"
            raise RunFailed(f"wall {how} at t = {t:.6g} s, z = {setup.wall.lines[0].z[i]:.6g} cm: "
                            f"|η| = {abs(eta[i]):.6g} cm > {setup.case.limits.max_displacement:g} R "
                            f"([solver] max_displacement)")


class EnergyBound:
    """Energy may never exceed the initial energy plus the work put in (a stable scheme's bound).

    Checked after every step with the margin ``[solver] energy_margin``: beyond
    it the scheme is unstable and the run stops, naming time and amounts.
    """

    def __init__(self, initial: float, margin: float):
        self.initial, self.margin, self.work, self.scale = initial, margin, 0.0, abs(initial)

    def check(self, t: float, terms: dict[str, float]) -> None:
        self.work += sum(v for k, v in terms.items() if k.startswith("work."))
        bound = self.initial + self.work
        self.scale = max(self.scale, abs(self.initial) + abs(self.work), abs(terms["energy.total"]))
        excess = terms["energy.total"] - bound
        if excess > self.margin * self.scale:
            raise RunFailed(f"energy grew beyond the work put in at t = {t:.6g} s: E = {terms['energy.total']:.6g} "
                            f"> E⁰ + work = {bound:.6g} (by {excess / self.scale:.3g} of the energy scale; "
                            f"[solver] energy_margin = {self.margin:g}): the scheme is unstable here")


@attrs.define
class Tally:
    """What the loop carries from step to step besides the state: the ledger and the counts.

    It is part of a checkpoint, so a resumed run goes on with the same numbers.
    """

    previous: float  #: the stored energy before the next step
    bound: EnergyBound
    steps: int = 0
    t: float = 0.0
    max_rel: float = 0.0
    iterations: list[float] = attrs.field(factory=list)
    peaks: dict[str, float] = attrs.field(factory=dict)
    wall_time_s: float = 0.0  #: wall time of earlier sessions of a resumed run
    #: the adaptive steps' controller record of the latest state (``State.extra["clock"]``; None for fixed steps)
    clock: dict | None = None
    #: the volume ledger (a run with a fluid)
    volume: VolumeLedger | None = None

    @classmethod
    def start(cls, setup: Setup, coupler: Coupler, state: State) -> Tally:
        """The tally of a run starting from ``state``: its stored energy, the case's energy and volume margins."""
        energy = sum(coupler.energy(setup, state).values())
        volume = VolumeLedger(setup.case.limits.volume_margin) if state.eta is not None else None
        return cls(energy, EnergyBound(energy, setup.case.limits.energy_margin), volume=volume)


@attrs.frozen(eq=False)
class Step:
    """One step of a run, as :func:`iterate_steps` yields it.

    Attributes
    ----------
    n : int
        Step number (1 for the first step).
    t : float
        Time at the end of the step (s).
    ledger : dict of str to float
        The energy ledger of the step: every stored-energy, work and
        dissipation term, ``energy.total``, ``energy.residual`` and
        ``energy.relative_residual`` (:func:`multilayer.runner.ledger.close`).
    probes : dict of str to float
        Each probe of ``[output] probes`` by name.
    diagnostics : dict of str to float
        The coupler's extra columns (e.g. ``iterations``); often empty.
    state : State
        The state at ``t`` (a value: fields in the wall's and the fluid's numbering).
    row : dict
        The step's row of ``series.csv``: ``step``, ``t``, the ledger, the
        diagnostics and the probes.
    """

    n: int
    t: float
    ledger: dict[str, float]
    probes: dict[str, float]
    diagnostics: dict[str, float]
    state: State
    row: dict[str, Any]


class Output(Protocol):
    """Where the steps go: the step's row (before it counts), its fields (after)."""

    def row(self, step: Step) -> None: ...

    def fields(self, step: Step) -> None: ...


#: what setting up a scene may raise that is a failure of the case, not a bug
SETUP_ERRORS = (ValueError, RuntimeError, np.linalg.LinAlgError)


@contextlib.contextmanager
def setting_up() -> Iterator[None]:
    """Around building a scene and its first state: a failure of the case becomes :class:`RunFailed`.

    >>> with setting_up():
    ...     raise ValueError("no such thing")
    Traceback (most recent call last):
    ...
    multilayer.runner.stepping.RunFailed: setting up the scene failed: no such thing
    """
    try:
        yield
    except SETUP_ERRORS as exc:
        raise RunFailed(f"setting up the scene failed: {exc}") from exc


def iterate_steps(setup: Setup, coupler: Coupler, state: State, tally: Tally, probes: Mapping[str, Any],
                  output: Output | None = None) -> Iterator[Step]:
    """Advance ``state`` to the case's end, one :class:`Step` per step (see the module's docstring).

    ``probes`` are the evaluators of :meth:`Setup.probe_rows`; ``tally`` is
    updated in place.  The guards raise :class:`RunFailed`; the coupler may
    raise :class:`~multilayer.coupling.contract.SchemeFailure`.  Closing the
    generator closes the coupler's.
    """
    eta_probes = [p.name for p in setup.case.output.probes if p.quantity == "eta"]
    meter = LumenVolume(setup.fluid.line) if tally.volume is not None else None
    with contextlib.closing(coupler.evolve(setup, state)) as advancing:
        for new, report in advancing:
            terms = ledger.close(report.stored, tally.previous, report.work, report.dissipation)
            tally.previous = terms["energy.total"]
            if meter is not None:
                terms.update(tally.volume.close(meter, report.parts(new)))
            check_state(setup, new, {**terms, **report.diagnostics})
            tally.iterations.append(report.diagnostics.get("iterations", math.nan))
            t_out = time.perf_counter()
            values = setup.probe_values(probes, new)
            row = {"step": new.n, "t": new.t, **terms, **report.diagnostics, **values}
            step = Step(new.n, new.t, terms, values, dict(report.diagnostics), new, row)
            if output is not None:
                output.row(step)
            tally.steps, tally.t, tally.clock = new.n, new.t, new.extra.get("clock")
            tally.max_rel = max(tally.max_rel, terms["energy.relative_residual"])
            for name in eta_probes:
                tally.peaks[name] = max(tally.peaks.get(name, 0.0), abs(row[name]))
            if output is not None:
                output.fields(step)
            setup.timings["output"] += time.perf_counter() - t_out
            try:
                tally.bound.check(new.t, terms)  # after the row is written: the row that breaks it is kept
            except RunFailed as exc:
                note = coupler.energy_bound_note(setup.case)
                if not note:
                    raise
                raise RunFailed(f"{exc}{note}") from exc
            if meter is not None:
                lost = tally.volume.excess(new.t, terms["volume.fluid"])
                if lost:
                    raise RunFailed(lost)
            yield step
