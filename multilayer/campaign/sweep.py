"""``multilayer sweep``: a grid over any case keys, each run in a folder named by its case digest.

Plan → execute → collect:

* :func:`plan` expands the case file's ``[sweep]`` table
  (:func:`read_sweep_table`) and every ``--vary`` (:func:`sweep_axes`,
  :mod:`multilayer.case.grid`) into resolved, validated cases
  (:class:`SweepRun`), each with its digest and folder ``runs/<digest[:12]>/``;
* :func:`multilayer.campaign.executor.execute` runs those not finished yet
  (:func:`pending`: a folder whose ``summary.json`` says ``ok`` for the same
  ``case_hash`` is skipped) — on an embedded local Dask cluster, an
  existing one (``--scheduler``), or here (``--jobs 1``);
* :func:`collect` measures every run from its results folder alone
  (:func:`multilayer.campaign.measures.measure`), and :func:`write_report`
  writes the rows into ``sweep.csv``, ``sweep.md`` and one figure per swept key.

The command line (its options, messages and exit codes) is
:mod:`multilayer.commands.sweep`.

See ``docs/sweeps.md``.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from multilayer.campaign.measures import measure
from multilayer.campaign.report import cell
from multilayer.campaign.variants import sanitize
from multilayer.case.casefile import load_case
from multilayer.case.files import read_case
from multilayer.case.grid import (
    Point,
    SweepTable,
    combinations,
    parse_varies,
    sweep_table,
    vary_axis,
)
from multilayer.plugin.problems import MISSING, CaseError, Problem
from multilayer.plugin.registry import Registry
from multilayer.results.campaign import claim
from multilayer.results.files import atomic_file, write_atomically
from multilayer.results.folder import holds_finished_run
from multilayer.results.reading import read_run, without_nan

#: characters of the digest in a run's folder name
DIGEST_CHARS = 12
RUNS = "runs"


@attrs.frozen
class SweepRun:
    """One planned run: the swept (key, value) pairs, the overrides that make it, its case's digest."""

    values: tuple[tuple[str, str], ...]
    overrides: tuple[str, ...]
    digest: str

    @property
    def folder(self) -> str:
        """Relative to the sweep folder: ``runs/<digest[:12]>``."""
        return f"{RUNS}/{self.digest[:DIGEST_CHARS]}"

    @property
    def label(self) -> str:
        return ", ".join(f"{k}={v}" for k, v in self.values) or self.digest[:DIGEST_CHARS]


def read_sweep_table(case_file: Path) -> SweepTable | None:
    """The ``[sweep]`` table of ``case_file`` (None without one); CaseError with its key paths when invalid."""
    data = read_case(case_file)  # bounded: a FIFO, a device, a huge or deeply nested file is a CaseError
    if "sweep" not in data:
        return None
    table, problems = sweep_table(data["sweep"])
    if problems:
        raise CaseError(problems)
    return table


def sweep_axes(table: SweepTable | None, varies: Sequence[str]) -> list[list[Point]]:
    """The axes of the sweep: the ``[sweep]`` table's, each ``--vary`` replacing a grid key or adding one.

    Raises
    ------
    CaseError
        A malformed ``--vary``, one that names a key of a ``zip`` group, or
        no axis at all.

    Examples
    --------
    >>> table = SweepTable(grid=(("time.dt", (1e-4, 5e-5)),))
    >>> [[p[0].override for p in axis] for axis in sweep_axes(table, ["time.dt=1e-3,2e-3", "mesh.nz=12,24"])]
    [['time.dt=1e-3', 'time.dt=2e-3'], ['mesh.nz=12', 'mesh.nz=24']]
    """
    table = table or SweepTable()
    varied = parse_varies(varies)
    zipped = {k for group in table.zips for k, _ in group}
    problems = [Problem("--vary", f"{key}=" + ",".join(values), "this key is varied together with others in "
                        "[sweep] zip; change it there") for key, values in varied if key in zipped]
    if problems:
        raise CaseError(problems)
    replaced = dict(varied)
    axes = [[(s,) for s in vary_axis(key, replaced.pop(key))] if key in replaced else axis
            for (key, _), axis in zip(table.grid, table.axes()[:len(table.grid)])]
    axes += table.axes()[len(table.grid):]
    axes += [[(s,) for s in vary_axis(key, values)] for key, values in replaced.items()]
    if not axes:
        raise CaseError([Problem("sweep", MISSING, "nothing to sweep: give the case a [sweep] table or use --vary")])
    return axes


def key_problems(case_file: Path, axes: Sequence[Sequence[Point]], overrides: Sequence[str],
                 registry: Registry) -> list[Problem]:
    """What is wrong with each axis alone: its first point applied to the case (after ``--set``).

    A key the case does not have (``time.dtt``, ``layers[3].young``) is
    reported once, with its key path, before every run that carries it.
    """
    problems: list[Problem] = []
    for axis in axes:
        try:
            load_case(case_file, (*overrides, *(s.override for s in axis[0])), registry)
        except CaseError as exc:
            problems += [p for p in exc.problems if p not in problems]
    return problems


def plan(case_file: Path, axes: Sequence[Sequence[Point]], overrides: Sequence[str], registry: Registry,
         ) -> tuple[list[SweepRun], dict[str, list[Problem]]]:
    """Every combination of the axes as a validated case: (the runs, the problems by run label).

    Overrides in order: ``--set``, then the swept values.  Runs whose
    resolved cases are equal (one digest) are planned once, under the
    first combination.
    """
    runs: dict[str, SweepRun] = {}
    invalid: dict[str, list[Problem]] = {}
    for point in combinations(axes):
        sets = (*overrides, *(s.override for s in point))
        values = tuple((s.key, s.value) for s in point)
        try:
            case = load_case(case_file, sets, registry)
        except CaseError as exc:
            invalid[SweepRun(values, sets, "").label] = exc.problems
            continue
        runs.setdefault(case.digest, SweepRun(values, sets, case.digest))
    return list(runs.values()), invalid


def done(run: SweepRun, out: Path) -> bool:
    """Whether ``out/<run.folder>`` holds this very run, finished ok (``summary.json``: status and case_hash)."""
    return holds_finished_run(out / run.folder, run.digest)


def pending(runs: Sequence[SweepRun], out: Path) -> list[SweepRun]:
    """The runs still to run: missing, failed, interrupted, running when their worker died, or of another case."""
    return [run for run in runs if not done(run, out)]


# -- collect -----------------------------------------------------------------------

#: the measured quantities of every row besides the probes' peaks: (column, label in plots)
QUANTITIES = (("wall_time_s", "wall time (s)"), ("dofs", "DOFs (count)"),
              ("max_relative_residual", "ledger relative residual (–)"), ("wave_speed", "wave speed (cm/s)"))


def collect(runs: Sequence[SweepRun], out: Path, registry: Registry) -> list[dict[str, Any]]:
    """One row per run, read from its results folder alone (:func:`multilayer.campaign.measures.measure`)."""
    rows = []
    for run in runs:
        m = measure(read_run(run.label, out / run.folder), None, registry)
        peaks = {f"peak_eta.{name}": e.get("peak") for name, e in m["probes"].items() if e["quantity"] == "eta"}
        rows.append({"digest": run.digest[:DIGEST_CHARS], **dict(run.values), "status": m["status"],
                     "wall_time_s": m["wall_time_s"], "dofs": m["dofs_total"],
                     "max_relative_residual": m["max_relative_residual"], **peaks,
                     "wave_speed": m["wave_speed_peak"], "reason": m["reason"], "folder": run.folder})
    return rows


def _columns(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    return list(dict.fromkeys(k for row in rows for k in row))


def write_csv(rows: Sequence[Mapping[str, Any]], path: Path) -> None:
    """``sweep.csv``: one row per run, every column of any row (empty where a run has none)."""
    columns = _columns(rows)
    with atomic_file(path, "w") as f:
        writer = csv.writer(f)
        writer.writerow(columns)
        writer.writerows([["" if row.get(c) is None else row.get(c) for c in columns] for row in rows])


def markdown(rows: Sequence[Mapping[str, Any]], keys: Sequence[str], command: str, figures: Sequence[str]) -> str:
    """``sweep.md``: the command, one table row per run, the figures."""
    columns = [c for c in _columns(rows) if c not in ("reason", "folder")]
    ok = sum(r["status"] == "ok" for r in rows)
    lines = ["# Sweep", "", "    " + command, "",
             f"{len(rows)} runs over {', '.join(f'`{k}`' for k in keys)}: {ok} ok, {len(rows) - ok} not. "
             f"Each run's folder is `runs/<digest>/` (the first {DIGEST_CHARS} characters of its case's digest).", "",
             "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(cell(r.get(c)).replace("|", "\\|") for c in columns) + " |" for r in rows]
    failed = [f"- `{r['digest']}` ({', '.join(f'{k}={r[k]}' for k in keys)}): {r['status']}: {r['reason']}"
              for r in rows if r["status"] != "ok"]
    if failed:
        lines += ["", "Not ok:", "", *failed]
    lines += ["", *(f"![{name}]({name})" for name in figures), ""]
    return "\n".join(lines)


def _number(text: str) -> float | None:
    try:
        return float(text)
    except (TypeError, ValueError):
        return None


def plot(rows: Sequence[Mapping[str, Any]], keys: Sequence[str], out: Path) -> list[str]:
    """One figure per swept key, ``sweep_<key>.png``: every measured quantity against it (ok runs only).

    A numeric key is a numeric axis; any other (an inline table) one tick
    per value.  Runs equal in the other keys are joined by a line.
    """
    # matplotlib is heavy (and results.figures loads it): imported only when the figures are drawn
    from matplotlib.figure import Figure

    from multilayer.results.figures import save_figure

    ok = [r for r in rows if r["status"] == "ok"]
    quantities = [(c, label) for c, label in QUANTITIES[:3]]
    quantities += [(c, f"peak η at {c.split('.', 1)[1]} (cm)") for c in _columns(rows) if c.startswith("peak_eta.")]
    quantities += [QUANTITIES[3]]
    written = []
    for key in keys:
        values = list(dict.fromkeys(str(r[key]) for r in rows))
        numeric = all(_number(v) is not None for v in values)
        position = {v: (_number(v) if numeric else i) for i, v in enumerate(values)}
        ncols = min(3, len(quantities))
        nrows = -(-len(quantities) // ncols)
        fig = Figure(figsize=(4.2 * ncols, 3.2 * nrows), layout="constrained")
        axes = np.atleast_1d(fig.subplots(nrows, ncols)).ravel()
        others = [k for k in keys if k != key]
        groups: dict[tuple, list[Mapping[str, Any]]] = {}
        for r in ok:
            groups.setdefault(tuple(str(r[k]) for k in others), []).append(r)
        for ax, (column, label) in zip(axes, quantities):
            drawn = False
            for group, members in groups.items():
                points = sorted((position[str(r[key])], r[column]) for r in members if r.get(column) is not None)
                if points:
                    name = ", ".join(f"{k}={v}" for k, v in zip(others, group))[:60] or None
                    ax.plot(*zip(*points), "o-", label=name)
                    drawn = True
            if not drawn:
                ax.text(0.5, 0.5, "not measured", ha="center", va="center", transform=ax.transAxes)
            ax.set_ylabel(label)
            ax.set_xlabel(key)
            if not numeric:
                ax.set_xticks(range(len(values)), [v[:24] for v in values], rotation=20)
            elif drawn:  # 20000 30000 ... run into each other on a slide: 2 3 ... × 10⁴
                ax.ticklabel_format(axis="x", style="sci", scilimits=(-2, 3), useMathText=True)
            ax.grid(alpha=0.3)
        for ax in axes[len(quantities):]:
            ax.set_visible(False)
        if len(groups) > 1 and len(groups) <= 8:
            axes[0].legend(fontsize="small")
        name = figure_name(key)
        save_figure(fig, claim(out, name))
        written.append(name)
    return written


def figure_name(key: str) -> str:
    """The file of the figure of the swept ``key``."""
    return f"sweep_{sanitize(key)}.png"


def write_plan(runs: Sequence[SweepRun], keys: Sequence[str], out: Path, case_file: Path,
               overrides: Sequence[str], command: str) -> None:
    """``plan.json``: the command and, per run, its digest, folder and swept values."""
    data = {"command": command, "case_file": str(case_file), "overrides": list(overrides), "keys": list(keys),
            "runs": [{"digest": r.digest, "folder": r.folder, "values": dict(r.values),
                      "overrides": list(r.overrides)} for r in runs]}
    write_atomically(claim(out, "plan.json"), json.dumps(without_nan(data), indent=2) + "\n")


def write_report(out: Path, rows: Sequence[Mapping[str, Any]], keys: Sequence[str], command: str) -> None:
    """``sweep.csv``, one ``sweep_<key>.png`` per swept key and ``sweep.md`` of the :func:`collect` rows in ``out``."""
    write_csv(rows, claim(out, "sweep.csv"))
    # matplotlib is heavy (results.figures loads it): imported only when the figures are drawn
    from multilayer.results.figures import slide_style

    with slide_style():
        figures = plot(rows, keys, out)
    write_atomically(claim(out, "sweep.md"), markdown(rows, keys, command, figures))
