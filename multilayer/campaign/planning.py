"""The grid of a study or a stability map: couplers × axes of settings, validated, then run.

* :func:`parse_couplers` reads ``--couplers`` into :class:`CouplerChoice` s and
  :func:`parse_study_varies` every ``--vary`` (the coupler is left to
  ``--couplers``); :func:`grid_options` checks them with ``--jobs`` and
  ``--out``;
* :func:`plan_grid` (and :func:`plan`, its ``--vary``-only form) turns them
  into :class:`Planned` runs, each a :class:`~multilayer.campaign.variants.Variant`
  (case file + overrides) with its results folder
  ``OUT/<coupler>/<key=value>/...``;
* :func:`invalid_runs` validates every run before any starts, and
  :func:`run_planned` runs them with :func:`multilayer.campaign.executor.execute`
  and reads each folder back.

:mod:`multilayer.campaign.study` and :mod:`multilayer.campaign.stability` both
plan and run their grids here; the ratio of a stability map is one more axis
of :class:`~multilayer.case.grid.Setting` s.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs

from multilayer.campaign.executor import Job, execute, print_err
from multilayer.campaign.variants import Variant, load_variants, sanitize, unique
from multilayer.case import grid
from multilayer.case.casefile import load_case
from multilayer.case.grid import Setting, combinations, vary_axis
from multilayer.case.keys import parse_value, split_values
from multilayer.plugin.problems import CaseError, Problem, did_you_mean
from multilayer.plugin.records import MODEL
from multilayer.plugin.registry import Registry
from multilayer.results.folder import holds_finished_run
from multilayer.results.reading import RunData, read_run

#: the folder (and label) of a study's ``--reference`` run, kept free in every grid
REFERENCE = "reference"
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_.+-]*$")


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
    if isinstance(value, Mapping) and MODEL in value:  # a plugin with its parameters: model(key=value,...)
        return f"{value[MODEL]}(" + ",".join(f"{k}={_text(v)}" for k, v in value.items() if k != MODEL) + ")"
    return str(value)


def coupler_label(model: str, params: Mapping[str, Any]) -> str:
    """``model``, or ``model[key=value,...]`` with parameters.

    >>> coupler_label("kinematic-splitting", {})
    'kinematic-splitting'
    >>> coupler_label("monolithic", {"scheme": "crank-nicolson", "beta": 0.25})
    'monolithic[scheme=crank-nicolson,beta=0.25]'
    >>> coupler_label("monolithic", {"scheme": {"model": "theta", "theta": 0.75}})
    'monolithic[scheme=theta(theta=0.75)]'
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


def parse_study_varies(texts: Sequence[str]) -> list[tuple[str, list[str]]]:
    """Every ``--vary KEY=A,B,...`` of a study or a stability map (:func:`multilayer.case.grid.parse_varies`).

    The coupler cannot be varied: ``--couplers`` chooses it.

    >>> parse_study_varies(["time.dt=1e-4,5e-5", "mesh.nz=12,24"])
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
        axes = parse_study_varies(varies)
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


def finished_run(variant: Variant, folder: Path, registry: Registry) -> bool:
    """True when ``folder`` holds an ok run of exactly ``variant``'s case (same digest)."""
    return holds_finished_run(folder, load_case(variant.case_file, variant.overrides, registry).digest)


def run_planned(variants: Sequence[Variant], folders: Mapping[str, Path], workers: int, registry: Registry,
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
