"""The steps of a coupler's run: fixed Δt, or Δt chosen by error (``[time] tolerance``), with rejection and retry.

A coupler that offers adaptive steps writes one step as a function
``advance(state, window) -> (new state, report)`` and hands it to
:func:`march`, which yields the accepted steps.  The state is a value, so
a rejected step is simply dropped: the retry starts from the same state.

Adaptive steps (:class:`Adaptive`, derivation in docs/theory.md, "Adaptive steps"):

* the error of a step is the scheme's local error estimate (a scheme that
  :attr:`~multilayer.numerics.timescheme.TimeScheme.estimates_error`: Crank–Nicolson's,
  BDF2's; :func:`multilayer.numerics.stepsize.local_error`: no extra linear solve; times
  the part that stays in the run's error, BDF2's α₀:
  :meth:`~multilayer.numerics.timescheme.TimeScheme.carried`) of
  the wall displacement d and of the fluid velocity's time integral X
  (:func:`fields`: the velocities through their integrals), each in the max
  norm over its DOFs relative to that field's size so far (:meth:`Adaptive.size`), or with
  ``time.size = "memory"`` over the last memory time W (its rate counted over W from the first
  step, its peak forgotten at the rate 1/W: :meth:`Adaptive.forgetting`);
  the largest of them is the step's relative error e.  A coupler whose error
  the predictor does not see puts its own estimate of a field in the new
  state's ``extra["estimate.<field>"]`` (used instead), and an error that
  only bounds the next step in ``extra["estimate.next.<field>"]`` (the
  kinematic splitting: theory §4, "The splitting's error");
* every step of the span W is allowed the same share of tol (``time.control``
  "per-step", the default): err = e · N_W / tol, N_W the steps of the last span
  W, the memory time (``time.memory``; by default the loads' shortest period,
  or ``time.end`` when no load repeats): all of the steps while tⁿ⁺¹ ≤ W;
  after, a count that forgets a step at the rate 1/W (:func:`steps_in_memory`).
  That is kₙ of the control below replaced by the span's mean step
  min(t, W)/N_W: for even steps the same allowance, but steps in
  proportion to |x'''|^(−1/3) instead of |x'''|^(−1/2), the fewest for errors
  that add up (``scripts/step_bound.py``); err then goes as kₙ^(p+1). A step
  is charged for the error it makes, not for what earlier steps left: with
  Crank–Nicolson its estimate drops the echo of an undamped (−1)ⁿ mode
  (:func:`unechoed`), which would otherwise be charged again at every step
  and, N_W growing as the steps shrink, drive them to ``time.dt_min``
  (a scheme that :attr:`~multilayer.numerics.timescheme.TimeScheme.undamped` carries such modes);
* or, with ``time.control = "per-unit-step"``, e is asked per unit of elapsed
  time, over at most the memory time W: err = e · min(tⁿ⁺¹, W) / (kₙ · tol), so a step
  may add tol·kₙ/min(tⁿ⁺¹, W) of the field's size and the errors of any span
  W add up to about tol — on a periodic run the allowed local error stops
  shrinking after one period; without a period it is the run's relative error;
* Gustafsson's PI controller (:class:`~multilayer.numerics.stepsize.Controller`)
  proposes the next step: per step from err with q = p + 1 and, by a
  controller of their own with q = 1, from the next-step errors, the smaller
  of the two; per unit step from the larger of err and the next-step errors
  with q = p; a step with err > 1 is rejected and retried
  smaller; one that would go below ``time.dt_min`` stops the run
  (:class:`SchemeFailure`, every row so far kept);
* the first two steps are ``time.dt`` (the estimate needs three old levels);
* the step of a scheme with a bounded step ratio (:attr:`~multilayer.numerics.timescheme.TimeScheme.max_ratio`)
  is at most :data:`~multilayer.numerics.stepsize.GROW` = 2 times
  the one before: variable-step BDF2 is zero-stable for ratios below 1 + √2 only
  (:meth:`~multilayer.numerics.timescheme.TimeScheme.with_ratio`), and a step after
  one clipped to land would otherwise jump back by up to 4;
* steps are clipped to land on ``time.end``, on every multiple of
  ``time.output_interval`` and on the loads' breakpoints (a linear table's
  rows, a pulse's end: :meth:`~multilayer.functions.loads.PressureLoad.next_breakpoint`),
  so no step straddles a kink of a load (two equal steps instead of a sliver);
* everything the controller carries (its proposal, its last error, the
  peaks, the counts) is the state's ``extra["clock"]``: a checkpoint keeps
  it, so a resumed run takes the same steps.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import attrs
import numpy as np

from multilayer.case.model import Case
from multilayer.coupling.contract import SchemeFailure, StepReport
from multilayer.numerics.stepsize import GROW, Controller, local_error
from multilayer.numerics.timescheme import TimeScheme
from multilayer.scene.setup import Setup
from multilayer.scene.state import State

#: the fields whose error an adaptive step controls, by name
FIELDS = ("wall.d", "fluid.X")


@attrs.frozen
class Window:
    """One step as a coupler takes it: number n of the old level, [t0, t1], Δt, the scheme (its step ratio set)."""

    n: int
    t0: float
    t1: float
    dt: float
    scheme: TimeScheme


Advance = Callable[[State, Window], tuple[State, StepReport]]


def march(setup: Setup, scheme: TimeScheme, state: State, advance: Advance) -> Iterator[tuple[State, StepReport]]:
    """The accepted steps from ``state`` to the case's end: fixed Δt, or :class:`Adaptive` with a tolerance.

    A step of a multi-stage scheme is its stages, each an ``advance`` with the stage's scheme over its
    sub-step (:func:`step`).
    """
    if not setup.case.time.adaptive:
        for n, t0, t1 in setup.windows(state.n):
            state, report = step(advance, state, Window(n, t0, t1, setup.dt, scheme))
            yield state, report
        return
    yield from Adaptive(setup, scheme).march(state, advance)


def step(advance: Advance, state: State, window: Window, integrating: bool = False) -> tuple[State, StepReport]:
    """One step of ``window.scheme`` from ``state``: its stages one after the other, the step's state and report.

    A single-stage scheme is one ``advance``.  A multi-stage scheme's stage k is an ``advance`` from the
    stage before's state with the stage's scheme over its sub-step (:meth:`TimeScheme.substeps
    <multilayer.numerics.timescheme.TimeScheme.substeps>`), so it reads, along the chain of states, the
    step's earlier stages and then the old levels; the step's state is the last stage's with the step's
    old levels behind it (the stages' values belong to the step alone), its report the stages'
    (:func:`merged`).  ``integrating``: each stage integrates the fluid velocity's X by its own rule
    (:func:`integrate`), for the error estimate of adaptive steps.
    """
    substeps = window.scheme.substeps(window.t0, window.t1, window.dt)
    if len(substeps) == 1:
        new, report = advance(state, window)
        return (integrate(state, new, window) if integrating else new), attrs.evolve(report, alpha=window.scheme.alpha)
    parts, current = [], state
    for scheme, t0, t1, dt in substeps:
        sub = Window(window.n, t0, t1, dt, scheme)
        new, report = advance(current, sub)
        if integrating:
            new = integrate(current, new, sub)
        parts.append((new, attrs.evolve(report, alpha=scheme.alpha)))
        current = new
    new = attrs.evolve(current, previous=state.trimmed(window.scheme.old_levels - 1))
    return new, merged(parts, window.scheme.alpha)


def merged(parts: list[tuple[State, StepReport]], alpha: tuple[float, ...]) -> StepReport:
    """The report of a step from its stages' (state, report), in order.

    The stored energy is the last stage's; work and dissipation are the stages' summed by column, so the
    ledger closes over the step when every stage's identity starts from what the stage before stored
    (a multi-stage scheme's stages chain their stored energies); the diagnostics are the last stage's
    (its ends' fluxes and pressures, at the step's end), each ``*relative_residual*`` column the largest
    of the stages'.  The stages themselves stay in ``stages``: the volume ledger closes each.
    """
    reports = [r for _, r in parts]

    def summed(group: str) -> dict[str, float]:
        out: dict[str, float] = {}
        for r in reports:
            for key, value in getattr(r, group).items():
                out[key] = out.get(key, 0.0) + value
        return out

    diagnostics = dict(reports[-1].diagnostics)
    for r in reports[:-1]:
        for key, value in r.diagnostics.items():
            if "relative_residual" in key:
                diagnostics[key] = max(diagnostics.get(key, 0.0), value)
    return StepReport(dict(reports[-1].stored), summed("work"), summed("dissipation"), diagnostics, alpha,
                      tuple(parts))


def fields(state: State) -> dict[str, np.ndarray]:
    """The controlled fields of ``state``, by the names of :data:`FIELDS` (those it has).

    ``wall.d`` is the displacement of every layer, the time integral of the
    wall velocity; ``fluid.X`` the time integral of the fluid velocity,
    X^{n+1} = Xⁿ + Δt (u^{n+1} + uⁿ)/2, carried in ``extra`` (:func:`integrate`).
    Not the velocities themselves: Crank–Nicolson carries stiff modes undamped,
    as (−1)ⁿ oscillations of V and u that no step size removes once they are
    there (on the pulse case the splitting's V jumps by 0.06 cm/s at a lumen
    DOF over a step of 5e-10 s).  Their midpoint values, which is what d and X
    integrate, are free of them, so the estimate sees the velocities' error
    through their integrals.
    """
    out = {}
    if state.wall is not None:
        out["wall.d"] = state.wall.d
    if "fluid.X" in state.extra:
        out["fluid.X"] = state.extra["fluid.X"]
    return out


def old_levels(state: State) -> list[State] | None:
    """[state, the one before, the one before that]: the levels an estimate of the next step reads; None before
    three exist (the first two steps of a run)."""
    old = state.history(3)
    return old if state.n >= 2 and old[-1].n == state.n - 2 else None


def integrate(state: State, new: State, window: Window) -> State:
    """``new`` with its fluid velocity integral X (0 at the start), by the step's own rule Σα_k X^{n+1−k} = Δt ū
    (the trapezoidal rule for Crank–Nicolson, BDF2 for BDF2: X is to u what the wall's d is to V)."""
    if getattr(new.fluid, "u", None) is None:
        return new
    S = window.scheme
    old = state.history(S.levels - 1)
    us = [new.fluid.u, *[x.fluid.u for x in old]]
    Xs = [x.extra.get("fluid.X") for x in old]
    Xs = [np.zeros_like(us[0]) if X is None else X for X in Xs]
    return attrs.evolve(new, extra={**new.extra, "fluid.X": S.displacement(S.average(us), Xs, window.dt)})


class Adaptive:
    """Steps chosen by error (module docstring)."""

    def __init__(self, setup: Setup, scheme: TimeScheme):
        time = setup.case.time
        self.setup, self.scheme = setup, scheme
        self.tol, self.end, self.first = time.tolerance, time.end, time.dt
        self.lo, self.hi = time.smallest, time.dt_max if time.dt_max is not None else math.inf
        self.interval = time.output_interval
        self.loads = setup.case.loads.histories()
        self.memory = time.memory_time(self.loads)
        self.per_step = time.sharing == "per-step"
        #: a field's size over the last memory time (``time.size = "memory"``) rather than so far
        self.over_memory = time.sizing(self.loads) == "memory"
        self.controller = Controller(scheme.order + 1, hold=True) if self.per_step else Controller(scheme.order)
        #: per step, an error that only bounds the next step (the splitting's defect, O(kₙ²) a step) has an err
        #: that goes as kₙ: a PI controller of its own, q = 1, settles it at 0.70 instead of q = 3's 0.35
        self.ahead = Controller(1) if self.per_step else None

    def start(self) -> dict[str, float]:
        """The controller's record before the first step."""
        return {"dt": self.first, "err": 1.0, "last": 0.0, "accepted": 0, "rejected": 0, "smallest": 0.0,
                "largest": 0.0, "refactorizations": 0, "steps_in_memory": 0.0, "held": 1.0,
                **{f"peak.{name}": 0.0 for name in FIELDS}}

    def output_time(self, t0: float) -> float:
        """The next output time after ``t0``: a multiple of the output interval, or the end."""
        if self.interval is None:
            return self.end
        k = math.floor(t0 / self.interval * (1.0 + 1e-12)) + 1
        return min(self.end, k * self.interval)

    def landing(self, t0: float) -> float:
        """The next time a step must land on after ``t0``: an output time or a load's breakpoint."""
        return min([self.output_time(t0), *(load.next_breakpoint(t0) for load in self.loads)])

    def window(self, state: State, proposal: float) -> Window:
        """The step from ``state`` of the proposed length, clipped to Δt_max and to land (no sliver)."""
        t0 = state.t
        dt = min(proposal, self.hi)
        steps = [x.t for x in state.history(3)]  # tⁿ, tⁿ⁻¹, tⁿ⁻² (repeated at the start)
        if math.isfinite(self.scheme.max_ratio) and steps[1] < t0:
            dt = min(dt, GROW * (t0 - steps[1]))
        land = self.landing(t0)
        if t0 + dt >= land - 1e-9 * dt:
            dt, t1 = land - t0, land
        else:
            if t0 + 2.0 * dt > land:
                dt = 0.5 * (land - t0)
            t1 = t0 + dt
        ratio = dt / (t0 - steps[1]) if steps[1] < t0 else 1.0
        previous = (t0 - steps[1]) / (steps[1] - steps[2]) if steps[2] < steps[1] else 1.0
        return Window(state.n, t0, t1, dt, self.scheme.with_ratio(ratio, previous))

    def factorizations(self) -> int:
        """Factorizations so far, every system of the run (the coupler's and the fluid's)."""
        stats = [*self.setup.solvers.values(), *([self.setup.fluid.stats] if self.setup.fluid is not None else [])]
        return sum(st.factorizations for st in stats)

    def error(self, state: State, new: State, dt: float, record: dict[str, float],
              count: float) -> tuple[dict[str, float] | None, dict[str, np.ndarray]]:
        """(err of the step ``state`` → ``new`` per field, None before three old levels exist; the
        ``echo.<field>`` the next step's :func:`unechoed` reads). ``count`` is N_W with this step
        (:func:`steps_in_memory`), the share of the tolerance under per-step control.

        A field's local error is the coupler's own estimate where it put one in
        ``new.extra["estimate.<field>"]`` (the splitting's), else the scheme's
        estimate :func:`local_error` of the field (times its ``carried``).  What a coupler puts in
        ``new.extra["estimate.next.<field>"]`` comes out as ``next.<field>``: an error
        that bounds the next step and does not reject this one.
        """
        old = old_levels(state)
        if old is None:
            return None, {}
        if "fluid.X" in new.extra and "fluid.X" not in old[-1].extra:  # the start: X⁰ = 0
            old[-1] = attrs.evolve(old[-1], extra={**old[-1].extra, "fluid.X": np.zeros_like(new.extra["fluid.X"])})
        k = [dt, old[0].t - old[1].t, old[1].t - old[2].t]
        levels = [fields(s) for s in old]
        share = count if self.per_step else min(new.t, self.memory) / dt  # a step may add tol/share
        out, raw = {}, {}
        for name, x in fields(new).items():
            scale = max(record[f"peak.{name}"], self.size(x, levels[0][name], new.t, dt))
            given = new.extra.get(f"estimate.{name}")
            if given is None:
                given = local_error(x, [lv[name] for lv in levels], k, self.scheme) * self.scheme.carried(k)
                if self.per_step and self.scheme.undamped:
                    given, raw[f"echo.{name}"] = unechoed(given, state.extra.get(f"echo.{name}"), k, self.scheme)
            estimates = {name: given, f"next.{name}": new.extra.get(f"estimate.next.{name}")}
            for key, e in estimates.items():
                if e is not None:
                    out[key] = float(np.max(np.abs(e))) / scale * share / self.tol if scale > 0.0 else 0.0
        return out, raw

    def next_factor(self, err: float, ahead: float, record: dict[str, float]) -> tuple[float, float]:
        """(the next step over this one, the growth held back) after an accepted step of error ``err`` and
        next-step error ``ahead``: per unit step one PI controller on the larger of them; per step the smaller of
        the factors of the step's controller on err and of :attr:`ahead`'s on the next-step error."""
        held = record.get("held", 1.0)
        if self.ahead is None or not ahead:
            return self.controller.accepted(max(err, ahead), record["err"], held)
        factor = min(self.controller.factor(err, record["err"]), self.ahead.factor(ahead, record.get("err_next", 1.0)))
        return self.controller.kept(factor, held)

    def size(self, x: np.ndarray, before: np.ndarray, t: float, dt: float) -> float:
        """A field's size at time t: max(|x|, min(t, W) |x − x_before|/Δt) in the max norm (W |x − x_before|/Δt
        with ``time.size = "memory"``).

        The second term is how far the field's rate over the step moves it in the
        time elapsed, or in the memory time W once more has elapsed: early in a run,
        a small fast transient is measured against it, not against the field's
        still tiny value.  Over the memory time from the first step ("memory"): on a
        periodic run the first period is measured as the later ones are.
        """
        span = self.memory if self.over_memory else min(t, self.memory)
        return max(float(np.max(np.abs(x))), span * float(np.max(np.abs(x - before))) / dt)

    def forgetting(self, dt: float) -> float:
        """What is left of a field's peak size after a step of ``dt``: 1 (the peak so far), or exp(−Δt/W) with
        ``time.size = "memory"`` (the size over the last W: a start's transient is forgotten as N_W forgets its
        steps)."""
        return math.exp(-dt / self.memory) if self.over_memory else 1.0

    def march(self, state: State, advance: Advance) -> Iterator[tuple[State, StepReport]]:
        """The accepted steps from ``state`` to ``time.end`` (module docstring)."""
        record = dict(state.extra.get("clock") or self.start())
        while state.t < self.end * (1.0 - 1e-12):
            window = self.window(state, record["dt"])
            counted = self.factorizations()
            new, report = step(advance, state, window, integrating=True)
            if record["last"] and (window.dt != record["last"]  # BDF2: a new ratio at the same Δt changes α₀ too
                                   or window.scheme.alpha != self.scheme.with_ratio(window.scheme.previous).alpha):
                record["refactorizations"] += self.factorizations() - counted
            count = steps_in_memory(record, new.t, window.dt, self.memory)  # N_W with this step
            errors, raw = self.error(state, new, window.dt, record, count)
            new = attrs.evolve(new, extra={k: v for k, v in new.extra.items() if not k.startswith("estimate.")})
            new = attrs.evolve(new, extra={**new.extra, **raw})
            err = None if errors is None else max((e for k, e in errors.items() if not k.startswith("next.")),
                                                   default=0.0)
            if err is not None and err > 1.0:
                record["rejected"] += 1
                proposal = window.dt * self.controller.rejected(err)
                if proposal < self.lo:
                    raise SchemeFailure(
                        f"adaptive steps: at t = {state.t:.6g} s the error (err = {err:.3g} × time.tolerance) asks "
                        f"for a step of {proposal:.3g} s < time.dt_min = {self.lo:.3g} s: loosen time.tolerance "
                        f"or lower time.dt_min (every step before is kept)")
                record["dt"] = proposal
                continue
            clipped = window.dt < min(record["dt"], self.hi)
            ahead = max((e for k, e in (errors or {}).items() if k.startswith("next.")), default=0.0)
            control = None if err is None else max(err, ahead)  # what sets the next step
            factor, held = (1.0, 1.0) if err is None else self.next_factor(err, ahead, record)
            proposal = max(window.dt * factor, record["dt"]) if clipped else window.dt * factor
            if proposal < self.lo:  # the error asks for steps below dt_min from here on: no end of them
                raise SchemeFailure(
                    f"adaptive steps: after t = {new.t:.6g} s the error (err = {control:.3g} × time.tolerance) asks "
                    f"for a step of {proposal:.3g} s < time.dt_min = {self.lo:.3g} s: loosen time.tolerance or "
                    f"lower time.dt_min (every step up to t = {state.t:.6g} s is kept)")
            record.update(steps_in_memory=count)
            if err is not None and self.ahead is not None:  # per step: each error's own PI memory
                record.update(err=err, err_next=ahead)
            elif err is not None:
                record.update(err=control)
            record.update(dt=min(proposal, self.hi), held=held,
                          last=window.dt, accepted=record["accepted"] + 1,
                          smallest=min(record["smallest"] or window.dt, window.dt),
                          largest=max(record["largest"], window.dt))
            old_fields = fields(state)
            for name, x in fields(new).items():
                record[f"peak.{name}"] = max(record[f"peak.{name}"] * self.forgetting(window.dt),
                                             self.size(x, old_fields.get(name, 0.0 * x), new.t, window.dt))
            landed = float(new.t == self.output_time(state.t))
            state = attrs.evolve(new, extra={**new.extra, "clock": dict(record)})
            yield state, attrs.evolve(report, diagnostics={
                **report.diagnostics, "dt": window.dt, "error.local": 0.0 if err is None else err, "landed": landed,
                "error.next": ahead, **{f"error.{name}": (errors or {}).get(name, 0.0) for name in FIELDS}})


def alternating(k: list[float], scheme: TimeScheme) -> float:
    """μ: the ``scheme``'s estimate (:func:`local_error`) of the undamped mode xⁿ = (−1)ⁿ on the steps ``k``.

    The mode that a stiff, undamped component leaves (amplification −1 when
    ωΔt ≫ 1), seen at xⁿ = 1: −8/13 for Crank–Nicolson's even steps; its size
    depends on the step ratios only.

    >>> class Midpoint:  # Crank–Nicolson's Milne factor on even steps (its own: multilayer_plugins/schemes)
    ...     def milne(self, k):
    ...         return 1.0 / 13.0
    >>> round(alternating([0.1, 0.1, 0.1], Midpoint()), 12), round(alternating([0.2, 0.1, 0.1], Midpoint()), 12)
    (-0.615384615385, -1.384615384615)
    """
    return float(local_error(np.array(-1.0), [np.array(1.0), np.array(-1.0), np.array(1.0)], k, scheme))


def unechoed(e: np.ndarray, before: np.ndarray | None, k: list[float],
             scheme: TimeScheme) -> tuple[np.ndarray, np.ndarray]:
    """(An undamped ``scheme``'s local error estimate ``e`` of a step without the echo of an undamped (−1)ⁿ mode,
    ``e``/μ for the next step's call).

    ``before`` is the step before's ``e``/μ (None: ``e`` is returned as it is),
    μ = :func:`alternating` of each step's ratios; the estimate is
    ½ μₙ₊₁ (eⁿ⁺¹/μₙ₊₁ + eⁿ/μₙ). A stiff mode that the scheme (Crank–Nicolson) carries
    undamped flips sign every step, and the predictor's miss of it is μ times
    its value, so eⁿ⁺¹/μₙ₊₁ = −eⁿ/μₙ and the estimate is 0 whatever the step
    ratios: an oscillation made once is not counted again at every later step
    (a step that makes one still counts half of it). A smooth error changes
    little from step to step: for it the estimate is eⁿ⁺¹ on even steps,
    0.78–1.10 of it at step ratios 2–0.8, and larger where steps shrink faster
    (1.4 at 0.5) (theory §4, "The echo of an undamped mode").

    >>> class Midpoint:  # Crank–Nicolson's Milne factor on even steps (its own: multilayer_plugins/schemes)
    ...     def milne(self, k):
    ...         return 1.0 / 13.0
    >>> k, cn = [0.1, 0.1, 0.1], Midpoint()
    >>> mu = alternating(k, cn)
    >>> unechoed(np.array([1.0, 2.0]), np.array([1.0, -2.0]) / mu, k, cn)[0]     # smooth, alternating
    array([1., 0.])
    """
    mu = alternating(k, scheme)
    if before is None:
        return e, e / mu
    return 0.5 * (e + mu * before), e / mu


def steps_in_memory(record: dict[str, float], t: float, dt: float, memory: float) -> float:
    """N_W after a step of ``dt`` to ``t``: the steps of the last memory time W, this one included.

    While t ≤ W every step so far; after, the count forgets at the rate 1/W
    (N ← N (1 − Δt/W) + 1), so even steps k hold it at W/k.

    >>> record = {"steps_in_memory": 0.0}
    >>> for n in range(1, 301):
    ...     record["steps_in_memory"] = steps_in_memory(record, n * 0.01, 0.01, 1.0)
    >>> round(record["steps_in_memory"], 9)          # 100 steps in W = 1 s, before and after t = W
    100.0
    """
    before = record.get("steps_in_memory", record.get("accepted", 0.0))  # an older record: every step so far
    return (before if t <= memory * (1.0 + 1e-12) else before * max(0.0, 1.0 - dt / memory)) + 1.0


def summary(record: dict[str, float] | None, case: Case) -> dict[str, object]:
    """The ``adaptive`` entry of ``summary.json`` from the last state's controller record (empty for fixed steps)."""
    time = case.time
    if time.tolerance is None or record is None:
        return {}
    return {"adaptive": {"tolerance": time.tolerance, "memory": time.memory_time(case.loads.histories()),
                         "control": time.sharing, "size": time.sizing(case.loads.histories()),
                         "accepted": int(record["accepted"]),
                         "rejected": int(record["rejected"]),
                         "dt_range": [record["smallest"], record["largest"]],
                         "factorizations_at_dt_changes": int(record["refactorizations"])}}
