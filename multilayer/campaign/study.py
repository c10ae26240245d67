"""``multilayer study``: speed against error of couplers × Δt (× mesh), in one command.

Plan → execute → collect:

* :func:`plan` turns ``--couplers`` and every ``--vary`` into a grid of runs,
  each a :class:`~multilayer.campaign.variants.Variant` (case file + overrides) with
  its results folder ``OUT/<coupler>/<key=value>/...``;
* :func:`multilayer.campaign.executor.execute` runs them (here with ``--jobs 1``,
  else on Dask), each into an ordinary results folder
  (:func:`multilayer.campaign.variants.run_variant`);
* :func:`collect` measures everything from those folders alone
  (:func:`multilayer.results.reading.read_run`): errors against a reference,
  observed orders, the Pareto front of wall time against error, the cost of
  reaching a target error; :func:`study_data` is the whole ``study.json``,
  which :func:`write_report` writes with ``study.md`` and the figures.

The command line (its options, messages and exit codes) is
:mod:`multilayer.commands.study`.

The measurements are pure functions of numbers and arrays
(:func:`relative_linf`, :func:`probe_errors`, :func:`observed_orders`,
:func:`pareto_front`, :func:`richardson`, :func:`richardson_order`,
:func:`cost_to_target`).  See ``docs/study.md``.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from multilayer.campaign.executor import Job, execute, print_err
from multilayer.campaign.variants import (
    Variant,
    load_variants,
    sanitize,
    unique,
)
from multilayer.case import grid
from multilayer.case.casefile import load_case
from multilayer.case.grid import Setting, combinations, vary_axis
from multilayer.case.keys import parse_value, split_values
from multilayer.plugin.problems import CaseError, Problem, did_you_mean
from multilayer.plugin.registry import Registry
from multilayer.results.folder import holds_finished_run
from multilayer.results.reading import (
    RunData,
    dof_counts,
    finite_rows,
    read_run,
    without_nan,
)

#: target peak errors of the cost table
TARGETS = (0.05, 0.01)
#: the coupler the costs are also given relative to, when it is in the study
BASELINE = "kinematic-splitting"
#: key paths a compared run may differ in from the reference (the reference may stop earlier: ``time.end``)
FREE_KEYS = ("title", "coupler", "time.dt", "time.end", "mesh", "output.every")
#: key paths in which the runs of the reference's own Δt sequence differ from it (Richardson)
SIBLING_KEYS = ("title", "time.dt", "output.every")
#: an observed order outside this range is not trusted for Richardson: the formal order is used
ORDER_RANGE = (0.5, 4.0)
REFERENCE = "reference"
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_.+-]*$")

# -- the grid ------------------------------------------------------------------


@attrs.frozen
class CouplerChoice:
    """One ``--couplers`` item: its label and the override that selects it (None: the case's own)."""

    label: str
    model: str
    override: str | None = None


@attrs.frozen
class Planned:
    """One run of the grid: a variant (labelled ``<coupler>/<key=value>/...``) and its results folder."""

    variant: Variant
    folder: str  #: relative to the study folder
    coupler: str  #: the coupler's label
    values: tuple[tuple[str, str], ...] = ()  #: the ``--vary`` (key, value) of this run

    @property
    def label(self) -> str:
        return self.variant.label


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def coupler_label(model: str, params: Mapping[str, Any]) -> str:
    """``model``, or ``model[key=value,...]`` with parameters.

    >>> coupler_label("kinematic-splitting", {})
    'kinematic-splitting'
    >>> coupler_label("monolithic", {"scheme": "crank-nicolson", "beta": 0.25})
    'monolithic[scheme=crank-nicolson,beta=0.25]'
    """
    if not params:
        return model
    return f"{model}[" + ",".join(f"{k}={_text(v)}" for k, v in params.items()) + "]"


def parse_couplers(text: str, names: Sequence[str]) -> list[CouplerChoice]:
    """The ``--couplers`` list: each item a coupler name or an inline table that replaces ``[coupler]``.

    CaseError at ``--couplers`` for an item that is neither, or names no
    coupler plugin in ``names``.

    >>> [c.label for c in parse_couplers('a, {model="b", beta=0.5}', ["a", "b"])]
    ['a', 'b[beta=0.5]']
    >>> parse_couplers('{model="b", beta=0.5}', ["b"])[0].override
    'coupler={model="b", beta=0.5}'
    >>> parse_couplers("aa", ["a", "b"])
    Traceback (most recent call last):
    ...
    multilayer.plugin.problems.CaseError: --couplers = 'aa': no such coupler plugin; did you mean 'a'?
    """
    try:
        items = split_values(text)
    except ValueError as exc:
        raise CaseError([Problem("--couplers", text, f"cannot split the values: {exc}")]) from None
    problems, choices = [], []
    for item in items:
        if not item:
            problems.append(Problem("--couplers", text, "an empty item", "two commas in a row, or one at an end?"))
            continue
        value = parse_value(item)
        if isinstance(value, str) and _NAME.match(value):
            model, params = value, {}
        elif isinstance(value, Mapping) and isinstance(value.get("model"), str):
            model, params = value["model"], {k: v for k, v in value.items() if k != "model"}
        else:
            problems.append(Problem("--couplers", item, 'expected a coupler name or an inline table '
                                    '{model="NAME", ...} replacing [coupler]'))
            continue
        if model not in names:
            problems.append(Problem("--couplers", model, "no such coupler plugin",
                                    did_you_mean(model, names) or "available: " + ", ".join(names)))
            continue
        choices.append(CouplerChoice(coupler_label(model, params), model, f"coupler={item}"))
    if problems:
        raise CaseError(problems)
    return [attrs.evolve(c, label=label) for c, label in zip(choices, unique([c.label for c in choices]))]


def parse_varies(texts: Sequence[str]) -> list[tuple[str, list[str]]]:
    """Every ``--vary KEY=A,B,...`` (:func:`multilayer.case.grid.parse_varies`); the coupler has ``--couplers``.

    >>> parse_varies(["time.dt=1e-4,5e-5", "mesh.nz=12,24"])
    [('time.dt', ['1e-4', '5e-5']), ('mesh.nz', ['12', '24'])]
    """
    return grid.parse_varies(texts, {"coupler": "the coupler is chosen with --couplers"})


def plan(case_file: Path, couplers: Sequence[CouplerChoice], varies: Sequence[tuple[str, Sequence[str]]],
         overrides: Sequence[str] = ()) -> list[Planned]:
    """The grid: every coupler × every combination of the varied values.

    Overrides in order: ``--set``, the coupler, the varied values.  The
    folder ``reference`` is kept free for ``--reference``.

    >>> runs = plan(Path("c.toml"), [CouplerChoice("a", "a", "coupler=a")], [("time.dt", ["1e-4", "5e-5"])],
    ...             ["mesh.nz=12"])
    >>> [(r.label, r.folder) for r in runs]
    [('a/time.dt=1e-4', 'a/time.dt=1e-4'), ('a/time.dt=5e-5', 'a/time.dt=5e-5')]
    >>> runs[1].variant.overrides
    ('mesh.nz=12', 'coupler=a', 'time.dt=5e-5')
    """
    return plan_grid(case_file, couplers, [vary_axis(key, values) for key, values in varies], overrides)


def plan_grid(case_file: Path, couplers: Sequence[CouplerChoice], axes: Sequence[Sequence[Setting]],
              overrides: Sequence[str] = ()) -> list[Planned]:
    """Every coupler × every combination of one setting per axis.

    Parameters
    ----------
    case_file : Path
        The case every run starts from.
    couplers : sequence of CouplerChoice
        The first level of the grid (folders ``<coupler>/``).
    axes : sequence of sequences of Setting
        The next levels, in order (folders ``<key=value>/``).
    overrides : sequence of str
        ``--set``, applied first; then the coupler's, then each axis's.

    Returns
    -------
    list of Planned
        Coupler-major, then the axes in order.  The folder ``reference``
        is kept free for ``--reference``.

    Examples
    --------
    >>> ratio = [Setting("ratio", "1", "layers[0].density=5.0")]
    >>> run, = plan_grid(Path("c.toml"), [CouplerChoice("a", "a", "coupler=a")],
    ...                  [ratio, vary_axis("time.dt", ["1e-4"])])
    >>> run.folder, run.values
    ('a/ratio=1/time.dt=1e-4', (('ratio', '1'), ('time.dt', '1e-4')))
    >>> run.variant.overrides
    ('coupler=a', 'layers[0].density=5.0', 'time.dt=1e-4')
    """
    coupler_folders = unique([REFERENCE, *(sanitize(c.label) for c in couplers)])[1:]
    axes = [list(zip(axis, unique([sanitize(f"{s.key}={s.value}") for s in axis]))) for axis in axes]
    runs = []
    for choice, coupler_folder in zip(couplers, coupler_folders):
        for combo in combinations([[(pair,) for pair in axis] for axis in axes]):
            values = tuple((s.key, s.value) for s, _ in combo)
            label = "/".join([choice.label, *(f"{k}={v}" for k, v in values)])
            sets = (*overrides, *([choice.override] if choice.override else []), *(s.override for s, _ in combo))
            runs.append(Planned(Variant(label, case_file, sets), "/".join([coupler_folder, *(f for _, f in combo)]),
                                choice.label, values))
    return runs


# -- running -------------------------------------------------------------------


def finished_run(variant: Variant, folder: Path, registry: Registry) -> bool:
    """True when ``folder`` holds an ok run of exactly ``variant``'s case (same digest)."""
    return holds_finished_run(folder, load_case(variant.case_file, variant.overrides, registry).digest)


def run_variants(variants: Sequence[Variant], folders: Mapping[str, Path], workers: int, registry: Registry,
                 plugins: Sequence[str] = (), scheduler: str | None = None, reuse: bool = False,
                 log: Callable[[str], None] = print_err) -> dict[str, RunData]:
    """Run every (validated) variant into ``folders[label]`` in this order, then read each folder back.

    :func:`multilayer.campaign.executor.execute` (here with one worker, else on
    Dask) with one line per finished run to ``log`` (stderr); the result is
    :func:`multilayer.results.reading.read_run` of each folder, by label, in the
    order of ``variants``, with the status and reason the run returned.
    With ``reuse``, a folder that already holds an ok run of the same case
    (:func:`finished_run`) is read as it is, not run again.

    Raises
    ------
    multilayer.campaign.executor.ExecutorError
        The runs cannot be started as asked (Dask missing for ``scheduler``).
    """
    kept = [v for v in variants if reuse and finished_run(v, folders[v.label], registry)]
    for v in kept:
        log(f"[reused] {v.label}: ok, already in {folders[v.label]}")
    work = [Job(v.label, v.case_file, v.overrides, folders[v.label]) for v in variants if v not in kept]
    status = execute(work, workers, registry, plugins, log=log, scheduler=scheduler)
    status.update({v.label: ("ok", "") for v in kept})
    return {v.label: read_run(v.label, folders[v.label], *status[v.label]) for v in variants}


# -- measurements (pure) -------------------------------------------------------


def _common_span(t: np.ndarray, t_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Masks of the rows of ``t`` and of ``t_ref`` inside the time span both cover."""
    if not len(t) or not len(t_ref):
        return None
    lo, hi = max(t[0], t_ref[0]), min(t[-1], t_ref[-1])
    on, ref_on = (t >= lo) & (t <= hi), (t_ref >= lo) & (t_ref <= hi)
    return (on, ref_on) if on.any() and ref_on.any() else None


def relative_linf(t: np.ndarray, y: np.ndarray, t_ref: np.ndarray, y_ref: np.ndarray) -> float | None:
    """max_t |y − y_ref| / max_t |y_ref|, the reference interpolated linearly onto ``t``.

    Only the times both series cover count: a row of ``t`` outside the
    reference's span is skipped.  The scale max |y_ref| is taken over the
    reference's own rows in that span, so it does not depend on the run.

    Parameters
    ----------
    t, y : ndarray
        The run's times (s) and values; rows with a NaN are left out.
    t_ref, y_ref : ndarray
        The reference's, on its own (usually finer) time grid.

    Returns
    -------
    float or None
        The relative error; None without common rows or when the reference
        is 0 on them.

    Examples
    --------
    >>> t_ref = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    >>> relative_linf(np.array([1.0, 2.0, 3.0]), np.array([0.0, 1.5, 0.0]), t_ref, np.array([0.0, 0.0, 1.0, 0.0, 0.0]))
    0.5
    >>> relative_linf(np.array([1.0, 2.0, 5.0]), np.array([0.0, 1.5, 9.0]), t_ref, np.array([0.0, 0.0, 1.0, 0.0, 0.0]))
    0.5
    """
    (t, y), (t_ref, y_ref) = finite_rows(t, y), finite_rows(t_ref, y_ref)
    span = _common_span(t, t_ref)
    if span is None:
        return None
    on, ref_on = span
    scale = float(np.max(np.abs(y_ref[ref_on])))
    if scale == 0.0:
        return None
    return float(np.max(np.abs(y[on] - np.interp(t[on], t_ref, y_ref)))) / scale


def probe_errors(t: np.ndarray, y: np.ndarray, t_ref: np.ndarray, y_ref: np.ndarray) -> dict[str, float | None]:
    """A run's ``eta`` series against the reference's, over the times both cover.

    ``relative_linf`` (:func:`relative_linf`); ``peak`` = max η and
    ``peak_time`` its (first) time, each series over its own rows;
    ``peak_error`` = |peak − peak_ref| / |peak_ref|; ``arrival_diff_s`` =
    peak_time − peak_time_ref.

    Parameters
    ----------
    t, y, t_ref, y_ref : ndarray
        As for :func:`relative_linf`.

    Returns
    -------
    dict
        ``relative_linf``, ``peak``, ``peak_time``, ``peak_ref``,
        ``peak_time_ref``, ``peak_error``, ``arrival_diff_s``; all None
        without common times.

    Examples
    --------
    >>> e = probe_errors(np.array([1.0, 2.0, 3.0]), np.array([0.0, 0.9, 0.3]),
    ...                  np.array([0.5, 1.5, 2.5, 3.5]), np.array([0.0, 0.5, 1.0, 0.2]))
    >>> e["peak_error"], e["arrival_diff_s"]
    (0.09999999999999998, -0.5)
    """
    none = dict.fromkeys(("relative_linf", "peak", "peak_time", "peak_ref", "peak_time_ref", "peak_error",
                          "arrival_diff_s"))
    (t, y), (t_ref, y_ref) = finite_rows(t, y), finite_rows(t_ref, y_ref)
    span = _common_span(t, t_ref)
    if span is None:
        return none
    on, ref_on = span
    i, j = int(np.argmax(y[on])), int(np.argmax(y_ref[ref_on]))
    peak, peak_ref = float(y[on][i]), float(y_ref[ref_on][j])
    peak_time, peak_time_ref = float(t[on][i]), float(t_ref[ref_on][j])
    return {
        "relative_linf": relative_linf(t, y, t_ref, y_ref),
        "peak": peak, "peak_time": peak_time, "peak_ref": peak_ref, "peak_time_ref": peak_time_ref,
        "peak_error": abs(peak - peak_ref) / abs(peak_ref) if peak_ref else None,
        "arrival_diff_s": peak_time - peak_time_ref,
    }


def observed_orders(dt: Sequence[float], errors: Sequence[float | None]) -> list[float | None]:
    """p = log(e_coarse/e_fine) / log(dt_coarse/dt_fine) between successive Δt (coarse to fine).

    Parameters
    ----------
    dt : sequence of float
        The time steps, strictly decreasing (ValueError otherwise).
    errors : sequence of float or None
        The error of each run.

    Returns
    -------
    list of float or None
        ``result[i]`` is the order between runs i and i + 1; None where an
        error is missing or not > 0.

    Examples
    --------
    >>> observed_orders([4e-4, 2e-4, 1e-4], [8.0, 4.0, None])
    [1.0, None]
    """
    if any(a <= b for a, b in zip(dt, dt[1:])):
        raise ValueError(f"Δt must decrease strictly: {list(dt)}")
    out: list[float | None] = []
    for (dt_c, e_c), (dt_f, e_f) in zip(zip(dt, errors), zip(dt[1:], errors[1:])):
        ok = e_c is not None and e_f is not None and e_c > 0 and e_f > 0
        out.append(math.log(e_c / e_f) / math.log(dt_c / dt_f) if ok else None)
    return out


def pareto_front(cost: Sequence[float], error: Sequence[float]) -> list[int]:
    """Indices of the points no other point beats: none as cheap and as accurate, and better in one.

    Parameters
    ----------
    cost, error : sequence of float
        Wall time and error of each point.

    Returns
    -------
    list of int
        The indices of the non-dominated points, in their order; two equal
        points do not beat each other.

    Examples
    --------
    >>> pareto_front([1.0, 2.0, 3.0, 2.5, 1.0], [0.5, 0.1, 0.01, 0.2, 0.6])
    [0, 1, 2]
    """
    return [i for i, (c, e) in enumerate(zip(cost, error))
            if not any(c2 <= c and e2 <= e and (c2 < c or e2 < e) for c2, e2 in zip(cost, error))]


def richardson(difference: float, ratio: float, order: float) -> float:
    """Richardson's error estimate of the finer of two runs: |X_fine − X_coarse| / (r^p − 1).

    For X(Δt) = X + C Δt^p and r = Δt_coarse/Δt_fine it is exactly |X(Δt_fine) − X|.

    Parameters
    ----------
    difference : float
        |X_fine − X_coarse|, in whatever measure X is compared.
    ratio : float
        r = Δt_coarse / Δt_fine > 1.
    order : float
        p, observed or formal.

    Returns
    -------
    float
        The estimated error of the finer run.

    Examples
    --------
    >>> richardson(0.3, 2.0, 1.0), richardson(0.4, 3.0, 2.0)
    (0.3, 0.05)
    """
    return difference / (ratio**order - 1.0)


def richardson_order(dt: Sequence[float], d_coarse: float, d_fine: float) -> float | None:
    """The order p of X(Δt) = X + C Δt^p seen in three runs Δt₀ > Δt₁ > Δt₂.

    ``d_coarse`` = |X(Δt₀) − X(Δt₁)|, ``d_fine`` = |X(Δt₁) − X(Δt₂)|.  With
    one ratio r it is log(d_coarse/d_fine)/log r; otherwise the root of
    (Δt₀^p − Δt₁^p)/(Δt₁^p − Δt₂^p) = d_coarse/d_fine in p ∈ [0.01, 20].

    Parameters
    ----------
    dt : sequence of three floats
        Δt₀ > Δt₁ > Δt₂.
    d_coarse, d_fine : float
        The two successive differences.

    Returns
    -------
    float or None
        p; None when a difference is not > 0 or there is no root.

    Examples
    --------
    >>> richardson_order([4.0, 2.0, 1.0], 12.0, 3.0)
    2.0
    >>> round(richardson_order([5.0, 2.0, 1.0], 21.0, 3.0), 12)
    2.0
    """
    if not (d_coarse > 0 and d_fine > 0):
        return None
    x0, x1 = dt[0] / dt[2], dt[1] / dt[2]
    q = d_coarse / d_fine
    if math.isclose(x0 / x1, x1, rel_tol=1e-9):
        return math.log(q) / math.log(x1)
    from scipy.optimize import brentq

    def mismatch(p: float) -> float:
        return (x0**p - x1**p) / (x1**p - 1.0) - q

    lo, hi = 0.01, 20.0
    if mismatch(lo) * mismatch(hi) > 0:
        return None
    return float(brentq(mismatch, lo, hi, xtol=1e-14, rtol=1e-14))


def cost_to_target(wall: Sequence[float], error: Sequence[float], target: float, finest: int | None = None,
                   order: float | None = None) -> dict[str, Any]:
    """Wall time to bring the error to ``target``, from one coupler's runs.

    The cheapest run with error ≤ target (``how`` = "measured"); else an
    extrapolation from the finest run ``finest`` with the observed order
    p: the time grows like 1/Δt and the error like Δt^p, so
    t = t_run·(e_run/target)^(1/p) ("estimated"); "not reached" without
    such a run or a p > 0.

    Parameters
    ----------
    wall, error : sequence of float
        Wall time (s) and error of each run of the coupler.
    target : float
        The error to reach.
    finest : int, optional
        Index of the run to extrapolate from.
    order : float, optional
        The observed order p of the error near that run.

    Returns
    -------
    dict
        ``how``, ``wall_time_s`` (None when not reached), ``run`` (the
        index measured or extrapolated from), ``order`` (p when estimated).

    Examples
    --------
    >>> cost_to_target([1.0, 2.0, 4.0], [0.2, 0.1, 0.05], 0.1)
    {'how': 'measured', 'wall_time_s': 2.0, 'run': 1, 'order': None}
    >>> cost_to_target([1.0, 2.0, 4.0], [0.2, 0.1, 0.05], 0.0125, finest=2, order=2.0)
    {'how': 'estimated', 'wall_time_s': 8.0, 'run': 2, 'order': 2.0}
    >>> cost_to_target([1.0], [0.2], 0.01, finest=0)["how"]
    'not reached'
    """
    met = [i for i, e in enumerate(error) if e <= target]
    if met:
        i = min(met, key=lambda k: wall[k])
        return {"how": "measured", "wall_time_s": wall[i], "run": i, "order": None}
    if finest is not None and order is not None and order > 0:
        return {"how": "estimated", "wall_time_s": wall[finest] * (error[finest] / target) ** (1.0 / order),
                "run": finest, "order": order}
    return {"how": "not reached", "wall_time_s": None, "run": None, "order": None}


def case_differences(a: Any, b: Any, free: Sequence[str] = (), path: str = "") -> list[str]:
    """Key paths at which two resolved cases differ, leaving out ``free`` paths (and what is under them).

    >>> case_differences({"time": {"dt": 1, "end": 2}, "fluid": {"mu": 1}, "layers": [{"E": 1}]},
    ...                  {"time": {"dt": 2, "end": 2}, "fluid": {"mu": 3}, "layers": [{"E": 2}]}, ["time.dt"])
    ['fluid.mu', 'layers[0].E']
    """
    if path in free:
        return []
    if isinstance(a, Mapping) and isinstance(b, Mapping):
        return [d for k in sorted(set(a) | set(b), key=str)
                for d in case_differences(a.get(k), b.get(k), free, f"{path}.{k}" if path else str(k))]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in case_differences(x, y, free, f"{path}[{i}]")]
    return [] if a == b else [path]


# -- collecting ------------------------------------------------------------------


def scheme_order(summary: Mapping[str, Any]) -> int | float:
    """The formal order of a run's coupler: ``summary["scheme"]["order"]``, or 1 when not written.

    >>> scheme_order({"scheme": {"name": "crank-nicolson", "order": 2}}), scheme_order({})
    (2, 1)
    """
    order = (summary.get("scheme") or {}).get("order")
    return order if isinstance(order, int | float) and not isinstance(order, bool) and order > 0 else 1


def eta_errors(run: RunData, reference: RunData, names: Sequence[str] | None = None) -> dict[str, dict[str, Any]]:
    """:func:`probe_errors` at every ``eta`` probe of ``run`` that the reference has too (same name).

    ``names`` (``--probes``) keeps only those probes.
    """
    ref_probes = {p["name"] for p in reference.probes if p["quantity"] == "eta"}
    return {p["name"]: {"z": p["z"], "line": p.get("line"),
                        **probe_errors(run.t, run.series[p["name"]], reference.t, reference.series[p["name"]])}
            for p in run.probes if p["quantity"] == "eta" and p["name"] in ref_probes
            and (names is None or p["name"] in names)}


def _worst(probes: Mapping[str, Mapping[str, Any]], key: str) -> float | None:
    values = [e[key] for e in probes.values() if e.get(key) is not None]
    return max(values) if values else None


def _row(planned: Planned, run: RunData, position: int) -> dict[str, Any]:
    s, case = run.summary, run.case
    dofs = dof_counts(s)
    return {
        "label": planned.label,
        "folder": planned.folder,
        "coupler": planned.coupler,
        "coupler_index": position,  # in --couplers: breaks ties between couplers of one order
        "model": (case.get("coupler") or {}).get("model"),
        "values": dict(planned.values),
        "overrides": list(planned.variant.overrides),
        "status": s.get("status", "failed"),
        "reason": s.get("reason", "" if s else "no summary.json written"),
        "wall_time_s": s.get("wall_time_s"),
        "steps": s.get("steps"),
        "dofs": dofs,
        "dofs_total": sum(dofs.values()) if dofs else None,
        "dt": (case.get("time") or {}).get("dt"),
        "nz": (case.get("mesh") or {}).get("nz"),
        "order": scheme_order(s),
        "reference": False,
        "compared": False,
        "not_compared": "",
        "probes": {},
        "error": None,
        "peak_error": None,
    }


def choose_reference(rows: Sequence[Mapping[str, Any]]) -> int | None:
    """Index of the finest ok run (smallest Δt, then largest nz) of the highest-order coupler.

    Ties between couplers of one order go to the first in ``--couplers``.

    >>> rows = [{"status": "ok", "order": 1, "coupler_index": 0, "dt": 1e-5, "nz": 10},
    ...         {"status": "ok", "order": 2, "coupler_index": 1, "dt": 1e-4, "nz": 10},
    ...         {"status": "ok", "order": 2, "coupler_index": 1, "dt": 5e-5, "nz": 10},
    ...         {"status": "failed", "order": 2, "coupler_index": 1, "dt": 1e-6, "nz": 10}]
    >>> choose_reference(rows)
    2
    """
    ok = [i for i, r in enumerate(rows) if r["status"] == "ok" and r["dt"] is not None]
    if not ok:
        return None
    return min(ok, key=lambda i: (-rows[i]["order"], rows[i]["coupler_index"], rows[i]["dt"], -(rows[i]["nz"] or 0)))


def _measured(row: Mapping[str, Any]) -> bool:
    return row["status"] == "ok" and not row["reference"] and row["error"] is not None


def _groups(rows: Sequence[dict[str, Any]]) -> dict[tuple, list[dict[str, Any]]]:
    """Runs of one coupler with the same values of every varied key but time.dt, coarse Δt first."""
    groups: dict[tuple, list[dict[str, Any]]] = {}
    for row in rows:
        if _measured(row):
            key = (row["coupler"], tuple((k, v) for k, v in row["values"].items() if k != "time.dt"))
            groups.setdefault(key, []).append(row)
    return {k: sorted(g, key=lambda r: -r["dt"]) for k, g in groups.items()}


def orders_table(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The observed orders of ``error`` and ``peak_error`` between successive Δt of each group."""
    out = []
    for (coupler, others), group in _groups(rows).items():
        dts = [r["dt"] for r in group]
        if len(set(dts)) < len(dts):
            continue  # the same Δt twice (a --set fixed it): no order
        for pair, p, q in zip(zip(group, group[1:]), observed_orders(dts, [r["error"] for r in group]),
                              observed_orders(dts, [r["peak_error"] for r in group])):
            out.append({"coupler": coupler, "group": dict(others), "coarse": pair[0]["label"],
                        "fine": pair[1]["label"], "dt_coarse": pair[0]["dt"], "dt_fine": pair[1]["dt"],
                        "error_order": p, "peak_error_order": q})
    return out


def _between(a: RunData, b: RunData, names: Sequence[str] | None = None) -> dict[str, float | None]:
    """``error`` and ``peak_error`` of ``a`` measured against ``b``."""
    probes = eta_errors(a, b, names)
    return {"error": _worst(probes, "relative_linf"), "peak_error": _worst(probes, "peak_error")}


def reference_error(reference: RunData, ref_order: float, rows: Sequence[Mapping[str, Any]],
                    runs: Mapping[str, RunData], names: Sequence[str] | None = None) -> dict[str, Any]:
    """Richardson's estimate of the reference's own ``error`` and ``peak_error``.

    From the two finest ok runs whose case is the reference's but for Δt
    (the reference itself when it is a run of the study): the difference d
    of the finest from the next, r their Δt ratio, p the order observed with
    a third run (:func:`richardson_order`) when it lies in
    :data:`ORDER_RANGE`, else the formal order.  The estimate
    d/(r^p − 1) is that of the finest run; a reference finer still is scaled
    by (Δt_ref/Δt_finest)^p.
    """
    by_dt: dict[float, Mapping[str, Any]] = {}
    for r in sorted(rows, key=lambda r: not r["reference"]):  # the reference first: it stands for its Δt
        if (r["status"] == "ok" and r["dt"] is not None
                and not case_differences(reference.case, runs[r["label"]].case, SIBLING_KEYS)):
            by_dt.setdefault(r["dt"], r)
    siblings = sorted(by_dt.values(), key=lambda r: -r["dt"])
    if len(siblings) < 2:
        return {"estimated": False, "note": "fewer than two ok runs of the reference's case that differ from it "
                                            "only in Δt"}
    chain = siblings[-3:]
    fine, coarse = chain[-1], chain[-2]
    ratio = coarse["dt"] / fine["dt"]
    dt_ref = (reference.case.get("time") or {}).get("dt", fine["dt"])
    d_fine = _between(runs[coarse["label"]], runs[fine["label"]], names)
    d_coarse = _between(runs[chain[0]["label"]], runs[coarse["label"]], names) if len(chain) == 3 else None
    out: dict[str, Any] = {"estimated": True, "fine": fine["label"], "coarse": coarse["label"],
                           "third": chain[0]["label"] if len(chain) == 3 else None, "ratio": ratio,
                           "formal_order": ref_order}
    for key in ("error", "peak_error"):
        observed = None
        if d_coarse is not None and d_coarse[key] is not None and d_fine[key] is not None:
            observed = richardson_order([r["dt"] for r in chain], d_coarse[key], d_fine[key])
        trusted = observed is not None and ORDER_RANGE[0] <= observed <= ORDER_RANGE[1]
        p = observed if trusted else ref_order
        scale = (dt_ref / fine["dt"]) ** p
        estimate = None if d_fine[key] is None else richardson(d_fine[key], ratio, p) * scale
        out[key] = {"difference": d_fine[key], "observed_order": observed, "order": p,
                    "order_from": "observed" if trusted else "formal", "scale": scale, "estimate": estimate}
    return out


def cost_table(rows: Sequence[dict[str, Any]], orders: Sequence[Mapping[str, Any]],
               couplers: Sequence[CouplerChoice]) -> list[dict[str, Any]]:
    """Per coupler and target peak error: :func:`cost_to_target`, and the ratio to :data:`BASELINE`'s."""
    out = []
    for choice in couplers:
        own = [r for r in rows if r["coupler"] == choice.label and _measured(r) and r["peak_error"] is not None
               and r["wall_time_s"] is not None]
        finest = min(range(len(own)), key=lambda i: (own[i]["dt"], -(own[i]["nz"] or 0))) if own else None
        order = next((o["peak_error_order"] for o in orders if own and o["fine"] == own[finest]["label"]), None)
        for target in TARGETS:
            cost = cost_to_target([r["wall_time_s"] for r in own], [r["peak_error"] for r in own], target,
                                  finest, order)
            out.append({"coupler": choice.label, "model": choice.model, "target": target,
                        "how": cost["how"], "wall_time_s": cost["wall_time_s"], "order": cost["order"],
                        "run": None if cost["run"] is None else own[cost["run"]]["label"]})
    baseline = next((c.label for c in couplers if c.model == BASELINE), None)
    for entry in out:
        base = next((e for e in out if e["coupler"] == baseline and e["target"] == entry["target"]), None)
        ok = base is not None and base["wall_time_s"] and entry["wall_time_s"] is not None
        entry["ratio_to_baseline"] = entry["wall_time_s"] / base["wall_time_s"] if ok else None
    return out


def collect(planned: Sequence[Planned], runs: Mapping[str, RunData], couplers: Sequence[CouplerChoice],
            reference: RunData | None = None, probes: Sequence[str] | None = None) -> dict[str, Any]:
    """Every number of ``study.json``, from the results folders read back (``runs`` by label).

    ``reference`` is the ``--reference`` run; without it the reference is
    :func:`choose_reference`'s.
    """
    index = {c.label: i for i, c in enumerate(couplers)}
    rows = [_row(p, runs[p.label], index[p.coupler]) for p in planned]
    if reference is not None:
        ref_order = scheme_order(reference.summary)
        ref_info = {"label": REFERENCE, "folder": REFERENCE, "source": "--reference",
                    "status": reference.summary.get("status", "failed")}
    else:
        i = choose_reference(rows)
        reference = None if i is None else runs[rows[i]["label"]]
        ref_order = None if i is None else rows[i]["order"]
        ref_info = {"label": None if i is None else rows[i]["label"],
                    "folder": None if i is None else rows[i]["folder"], "source": "finest run",
                    "status": None if i is None else "ok"}
        if i is not None:
            rows[i]["reference"] = True
    usable = reference is not None and reference.summary.get("status") == "ok"
    if reference is not None:
        ref_case = reference.case
        ref_info.update({"coupler": ref_case.get("coupler"), "dt": (ref_case.get("time") or {}).get("dt"),
                         "nz": (ref_case.get("mesh") or {}).get("nz"), "order": ref_order,
                         "wall_time_s": reference.summary.get("wall_time_s")})
    for row in rows:
        if row["reference"] or row["status"] != "ok" or not usable:
            continue
        run = runs[row["label"]]
        differs = case_differences(reference.case, run.case, FREE_KEYS)
        if differs:
            row["not_compared"] = "its case differs from the reference's at " + ", ".join(differs)
            continue
        row["compared"] = True
        row["probes"] = eta_errors(run, reference, probes)
        row["error"] = _worst(row["probes"], "relative_linf")
        row["peak_error"] = _worst(row["probes"], "peak_error")
    orders = orders_table(rows)
    measured = [r for r in rows if _measured(r) and r["wall_time_s"] is not None]
    front = pareto_front([r["wall_time_s"] for r in measured], [r["error"] for r in measured])
    ref_info["richardson"] = (reference_error(reference, ref_order, rows, runs, probes) if usable
                              else {"estimated": False, "note": "no ok reference"})
    return {
        "reference": ref_info,
        "space_error_included": usable and any(r["compared"] and r["nz"] != ref_info["nz"] for r in rows),
        "runs": rows,
        "orders": orders,
        "pareto": sorted((measured[i]["label"] for i in front),
                         key=lambda label: next(r["wall_time_s"] for r in measured if r["label"] == label)),
        "cost_to_target": cost_table(rows, orders, couplers),
    }


# -- report ----------------------------------------------------------------------

ERROR_AXIS = "relative L∞ error of η (max over probes)"


def _pct(value: float | None) -> str:
    return "—" if value is None else f"{100 * value:.3g} %"


def markdown(data: Mapping[str, Any]) -> str:
    """``study.md``: the command, the reference, then runs, orders, Pareto front and costs."""
    from multilayer.campaign.report import cell

    ref, rows = data["reference"], data["runs"]
    lines = [f"# Study: {data['title']}" if data["title"] else "# Study", "", "    " + data["command"], ""]
    if ref["label"] is None:
        lines += ["No reference: no run ended ok, so no error is measured.", ""]
    else:
        how = ("`--reference`, run into `reference/`" if ref["source"] == "--reference"
               else "the finest run of the highest-order coupler")
        lines += [f"Reference: `{ref['label']}` ({how}; status {ref['status']}, Δt = {cell(ref.get('dt'))} s, "
                  f"nz = {cell(ref.get('nz'))}, formal order {cell(ref.get('order'))}).", ""]
        rich = ref["richardson"]
        if rich.get("estimated"):
            parts = [f"{name} ≈ {_pct(rich[key]['estimate'])} (p = {cell(rich[key]['order'])}, "
                     f"{rich[key]['order_from']})" for key, name in (("error", "error"), ("peak_error", "peak error"))]
            scaled = (f", times (Δt_ref/Δt_fine)^p = {cell(rich['error']['scale'])} for the reference's Δt"
                      if rich["error"]["scale"] != 1.0 else "")
            lines += [f"Its own error by Richardson from `{rich['coarse']}` and `{rich['fine']}` (Δt ratio "
                      f"{cell(rich['ratio'])}{scaled}): " + "; ".join(parts) + ". Errors below that are not resolved.",
                      ""]
        else:
            lines += [f"Its own error is not estimated: {rich['note']}.", ""]
    if data["space_error_included"]:
        lines += ["Some runs are on another mesh (nz) than the reference: their error includes the space "
                  "error, not only the time error.", ""]
    lines += ["`error`: max over the η probes of max_t |η − η_ref| / max_t |η_ref|; `peak error`: max over the "
              "η probes of |max_t η − max_t η_ref| / |max_t η_ref|; `arrival`: the largest |time of max η − the "
              "reference's| over the probes.", ""]
    if isinstance(data.get("probes"), list):
        lines += ["The η probes measured (`--probes`): " + ", ".join(f"`{p}`" for p in data["probes"]) + ".", ""]
    lines += ["## Runs", "", "| run | status | Δt (s) | nz | wall time (s) | steps | DOFs | error | peak error "
              "| arrival (s) |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        arrivals = [abs(e["arrival_diff_s"]) for e in r["probes"].values() if e["arrival_diff_s"] is not None]
        error = "(reference)" if r["reference"] else ("not compared" if r["not_compared"] else cell(r["error"]))
        lines.append(f"| `{r['label']}` | {r['status']} | {cell(r['dt'])} | {cell(r['nz'])} | "
                     f"{cell(r['wall_time_s'])} | {cell(r['steps'])} | {cell(r['dofs_total'])} | {error} | "
                     f"{cell(r['peak_error'])} | {cell(max(arrivals) if arrivals else None)} |")
    notes = [f"- `{r['label']}`: {r['reason'] or r['not_compared']}" for r in rows
             if r["status"] != "ok" or r["not_compared"]]
    if notes:
        lines += ["", "Failed or not compared:", "", *notes]
    lines += ["", "## Observed orders", ""]
    if data["orders"]:
        lines += ["p = log(e_coarse/e_fine) / log(Δt_coarse/Δt_fine) between successive Δt of one coupler "
                  "(other keys equal). Against a reference of the same Δt sequence the pair next to it "
                  "over-estimates p (its error is the whole difference to a nearby run).", "",
                  "| coupler | other keys | Δt coarse → fine (s) | order of error | order of peak error |",
                  "|---|---|---|---|---|"]
        for o in data["orders"]:
            others = ", ".join(f"{k}={v}" for k, v in o["group"].items()) or "—"
            lines.append(f"| `{o['coupler']}` | {others} | {cell(o['dt_coarse'])} → {cell(o['dt_fine'])} | "
                         f"{cell(o['error_order'])} | {cell(o['peak_error_order'])} |")
    else:
        lines.append("No order: no two measured runs of one coupler differ only in Δt.")
    lines += ["", "## Pareto front", "", "The runs no other run beats on both wall time and error; slower "
              "runs in this table are more accurate. A run not listed is slower and less accurate than one "
              "that is.", ""]
    by_label = {r["label"]: r for r in rows}
    if data["pareto"]:
        lines += ["| run | wall time (s) | error | peak error |", "|---|---|---|---|"]
        lines += [f"| `{label}` | {cell(by_label[label]['wall_time_s'])} | {cell(by_label[label]['error'])} | "
                  f"{cell(by_label[label]['peak_error'])} |" for label in data["pareto"]]
    else:
        lines.append("No run with a measured error.")
    lines += ["", "## Cost to reach a target peak error", "",
              "The cheapest run within the target (measured); otherwise t_run·(e_run/target)^(1/p) from the "
              "coupler's finest run and the observed order p of its peak error (estimated).", ""]
    costs = data["cost_to_target"]
    baseline = any(c["model"] == BASELINE for c in costs)
    head = ["coupler"]
    for target in TARGETS:
        head += [f"{_pct(target)}: wall time (s)"] + ([f"{_pct(target)}: × {BASELINE}"] if baseline else [])
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for coupler in dict.fromkeys(c["coupler"] for c in costs):
        cells = [f"`{coupler}`"]
        for target in TARGETS:
            c = next(e for e in costs if e["coupler"] == coupler and e["target"] == target)
            if c["how"] == "measured":
                cells.append(f"{cell(c['wall_time_s'])} (`{c['run']}`)")
            elif c["how"] == "estimated":
                cells.append(f"{cell(c['wall_time_s'])} (estimated, p = {cell(c['order'])})")
            else:
                cells.append("not reached")
            if baseline:
                cells.append(cell(c["ratio_to_baseline"]))
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", "![error against wall time](pareto.png)", "", "![error against Δt](orders.png)", ""]
    return "\n".join(lines)


def plot(data: Mapping[str, Any], out: Path) -> None:
    """``pareto.png`` (error against wall time) and ``orders.png`` (error against Δt), log–log."""
    from matplotlib.figure import Figure

    from multilayer.results.figures import save_figure

    rows = data["runs"]
    fig = Figure(figsize=(7, 5), layout="constrained")
    ax = fig.subplots()
    colours = {}
    for (coupler, _), group in _groups(rows).items():  # a line per Δt sweep, one colour per coupler
        group = [r for r in group if r["error"] > 0 and r["wall_time_s"] is not None]
        if group:
            line, = ax.plot([r["wall_time_s"] for r in group], [r["error"] for r in group], "o-",
                            color=colours.get(coupler), label=None if coupler in colours else coupler)
            colours.setdefault(coupler, line.get_color())
    front = [r for r in rows if r["label"] in data["pareto"] and r["error"] > 0]
    if front:
        ax.plot([r["wall_time_s"] for r in front], [r["error"] for r in front], "o", ms=12, mfc="none",
                color="black", label="Pareto front")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.legend(fontsize="small")
    else:
        ax.text(0.5, 0.5, "no measured error", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel("wall time (s)")
    ax.set_ylabel(ERROR_AXIS)
    ax.set_title(f"against {data['reference']['label']}", fontsize="medium")
    ax.grid(alpha=0.3, which="both")
    save_figure(fig, out / "pareto.png")

    fig = Figure(figsize=(7, 5), layout="constrained")
    ax = fig.subplots()
    groups = _groups(rows)
    anchor = None
    for (coupler, others), group in groups.items():
        group = [r for r in group if r["error"] > 0]
        if not group:
            continue
        name = coupler + "".join(f", {k}={v}" for k, v in others)
        ax.plot([r["dt"] for r in group], [r["error"] for r in group], "o-", label=name)
        anchor = anchor or (group[0]["dt"], group[0]["error"], group[-1]["dt"])
    if anchor is not None:
        dt0, e0, dt1 = anchor
        x = np.array([min(dt1, dt0 / 2), dt0])
        for slope, dashes in ((1, (4, 2)), (2, (1, 2))):
            ax.plot(x, e0 * (x / dt0) ** slope, color="gray", ls="--", dashes=dashes, label=f"slope {slope}")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.legend(fontsize="small")
    else:
        ax.text(0.5, 0.5, "no measured error", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel("Δt (s)")
    ax.set_ylabel(ERROR_AXIS)
    ax.grid(alpha=0.3, which="both")
    save_figure(fig, out / "orders.png")


# -- the options, and what the command writes --------------------------------------


def _own_coupler(case_file: Path, overrides: Sequence[str], registry: Registry) -> CouplerChoice:
    case = load_case(case_file, overrides, registry)
    return CouplerChoice(case.coupler.model, case.coupler.model)


def grid_options(case_file: Path, out: Path, couplers: str | None, varies: Sequence[str], jobs: int,
                 overrides: Sequence[str], registry: Registry,
                 ) -> tuple[list[CouplerChoice], list[tuple[str, list[str]]], list[Problem]]:
    """The options a grid command shares: ``--couplers``, every ``--vary``, ``--jobs``, ``--out``.

    Returns
    -------
    tuple
        The couplers (the case's own when ``couplers`` is None and the
        options are valid), the ``--vary`` axes, and every problem found in
        the command line; with problems the first two may be incomplete.

    Raises
    ------
    CaseError
        The case file itself is invalid (found while reading its own
        coupler).
    """
    problems: list[Problem] = []
    if jobs < 1:
        problems.append(Problem("--jobs", jobs, "expected an integer >= 1 (runs at once)"))
    choices: list[CouplerChoice] = []
    axes: list[tuple[str, list[str]]] = []
    try:
        choices = parse_couplers(couplers, registry.names("coupler")) if couplers is not None else []
    except CaseError as exc:
        problems += exc.problems
    try:
        axes = parse_varies(varies)
    except CaseError as exc:
        problems += exc.problems
    if out.exists() and not out.is_dir():
        problems.append(Problem("--out", str(out), "a file, not a folder"))
    if not problems and not choices:
        choices = [_own_coupler(case_file, overrides, registry)]
    return choices, axes, problems


def invalid_runs(variants: Sequence[Variant], registry: Registry) -> dict[str, list[Problem]]:
    """Validate every run before any starts: the problems by label (empty when every run is valid).

    :func:`multilayer.campaign.variants.invalid_message` puts them in words.
    """
    return load_variants(variants, registry, snapshots=False)[1]


def unknown_probes(names: Sequence[str], runs: Mapping[str, RunData]) -> list[Problem]:
    """A problem at ``--probes`` for each name that is not an η probe of any of the runs.

    >>> case = {"output": {"probes": [{"name": "eta_mid", "quantity": "eta"}]}}
    >>> run = RunData("a", Path("a"), {"case": case}, {"eta_mid": []})
    >>> [str(p) for p in unknown_probes(["eta_mid", "eta_mdi"], {"a": run})]
    ["--probes = 'eta_mdi': not an η probe of these runs; did you mean 'eta_mid'?"]
    """
    known = {p["name"] for r in runs.values() for p in r.probes if p["quantity"] == "eta"}
    return [Problem("--probes", name, "not an η probe of these runs",
                    did_you_mean(name, sorted(known)) or f"η probes: {', '.join(sorted(known))}")
            for name in names if name not in known]


def study_data(planned: Sequence[Planned], runs: Mapping[str, RunData], couplers: Sequence[CouplerChoice],
               axes: Sequence[tuple[str, Sequence[str]]], probes: Sequence[str] | None, *, command: str,
               case_file: Path, overrides: Sequence[str]) -> dict[str, Any]:
    """The whole of ``study.json``: what was asked (the command line, the case, the grid), then :func:`collect`.

    ``runs`` holds every planned run by label, and the ``--reference`` run
    under :data:`REFERENCE` when there is one.
    """
    data = {
        "command": command,
        "case_file": str(case_file),
        "title": next((r.case.get("title", "") for r in runs.values() if r.case), ""),
        "overrides": list(overrides),
        "couplers": [attrs.asdict(c) for c in couplers],
        "vary": [{"key": k, "values": v} for k, v in axes],
        "targets": list(TARGETS),
        "probes": list(probes) if probes is not None else "every η probe",
        **collect(planned, runs, couplers, runs.get(REFERENCE), probes),
    }
    for row in data["runs"]:
        del row["coupler_index"]
    return data


def write_report(out: Path, data: Mapping[str, Any]) -> None:
    """``study.json``, ``study.md``, ``pareto.png`` and ``orders.png`` of ``data`` in the folder ``out``."""
    (out / "study.json").write_text(json.dumps(without_nan(data), indent=2, allow_nan=False) + "\n")
    (out / "study.md").write_text(markdown(data))
    plot(data, out)
