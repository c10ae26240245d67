"""The Python API: load a case, run it with or without a results folder, step through it, read results back.

What ``multilayer validate``, ``multilayer run`` and a results folder offer
on the command line, as functions that return Python values::

    import multilayer as ml

    case = ml.load_case("cases/pulse-koiter-thick.toml", {"time.end": 0.002})
    res = ml.run(case)                       # in memory: nothing is written
    res.series["energy.relative_residual"]   # numpy arrays, one value per step
    for step in ml.steps(case):              # or one step at a time
        ...

The user's manual is ``docs/python-api.md``.
"""

from __future__ import annotations

import contextlib
import math
import numbers
import os
import re
from collections.abc import Callable, Generator, Iterable, Mapping
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from multilayer.case.casefile import load_case as _load_case
from multilayer.case.model import Case
from multilayer.coupling.build import prepare
from multilayer.coupling.contract import SchemeFailure
from multilayer.numerics.threads import blas_threads
from multilayer.plugin.problems import CaseError, Problem
from multilayer.plugin.registry import Registry
from multilayer.results.files import ResultsError
from multilayer.results.reading import lumen_eta, lumen_field, lumen_wss, read_run
from multilayer.runner.held import HeldResults
from multilayer.runner.loop import run_case, run_held
from multilayer.runner.stepping import RunFailed, Step, Tally, iterate_steps, setting_up

__all__ = ["ArgumentError", "Case", "CaseError", "Results", "ResultsError", "RunFailed", "Step", "load_case",
           "read_results", "run", "steps"]


class ArgumentError(TypeError, ValueError):
    """A function of the Python API given an argument of the wrong type or value; the message names it."""


def _path_arg(function: str, name: str, value: Any, optional: bool = False) -> None:
    if (value is None and optional) or isinstance(value, (str, os.PathLike)):
        return
    raise ArgumentError(f"{function}({name}=...): expected a path (str or os.PathLike){' or None' if optional else ''},"
                        f" got {type(value).__name__} {value!r:.60}")


def _case_arg(function: str, case: Any) -> None:
    if isinstance(case, Case):
        return
    if isinstance(case, (str, os.PathLike)):
        raise ArgumentError(f"{function}(case=...): expected a Case, got the path {str(case)!r}: read it first, "
                            f"multilayer.load_case({str(case)!r})")
    raise ArgumentError(f"{function}(case=...): expected a Case (from multilayer.load_case), got "
                        f"{type(case).__name__} {case!r:.60}")

#: η(z, t) on the lumen: (z, t, eta) with eta[i, j] = η(t[i], z[j])
LumenField = tuple[np.ndarray, np.ndarray, np.ndarray]


# -- loading ------------------------------------------------------------------------------------------------
def load_case(path: str | os.PathLike[str], overrides: Iterable[str] | Mapping[str, Any] = (), *,
              registry: Registry | None = None) -> Case:
    """Read a case file, apply overrides and validate it, as ``multilayer validate`` does.

    Parameters
    ----------
    path : path-like
        The TOML case file; table files it names are relative to its folder.
    overrides : iterable of str, or mapping
        ``"key=value"`` strings, exactly as ``--set`` takes them
        (``"time.dt=5e-5"``, ``'layers[1]={model="linear-elastic", ...}'``),
        or a mapping of key paths to Python values
        (``{"time.dt": 5e-5, "fluid": "none", "coupler": {"model": "monolithic"}}``):
        numbers, booleans, strings, lists and dicts, each written as the
        TOML value it is (a string stays a string).
    registry : Registry, optional
        The plugins to validate against; every installed one by default.

    Returns
    -------
    Case
        The validated case (``case.resolved`` is the full case as data,
        ``case.digest`` its hash).

    Raises
    ------
    CaseError
        Listing every problem found, one per line, each with its key path
        (``exc.problems`` are :class:`~multilayer.plugin.problems.Problem` records).

    Examples
    --------
    In a source checkout, with the installed plugins (``tests/test_api.py`` runs these lines)::

        case = load_case("cases/membrane-mode.toml", {"time.end": 0.001, "mesh.nz": 16})
        case.time.steps, case.mesh.nz                                  # (50, 16)
        load_case("cases/membrane-mode.toml", ["layers[0].tension=-1"])
        # CaseError: layers[0].tension = -1: expected a number >= 0.0 (dyn/cm) (from --set)
    """
    _path_arg("load_case", "path", path)
    if isinstance(overrides, str):
        overrides = [overrides]
    elif isinstance(overrides, Mapping):
        if not all(isinstance(k, str) for k in overrides):
            raise ArgumentError("load_case(overrides=...): a mapping's keys are key paths (str), like 'time.dt'")
        overrides = _override_strings(overrides)
    else:
        items = list(overrides) if isinstance(overrides, Iterable) else None
        if items is None or not all(isinstance(o, str) for o in items):
            raise ArgumentError(f"load_case(overrides=...): expected 'key=value' strings or a mapping of key paths "
                                f"to values, got {type(overrides).__name__} {overrides!r:.60}")
        overrides = items
    return _load_case(path, list(overrides), registry)


def _override_strings(values: Mapping[str, Any]) -> list[str]:
    """``{"time.dt": 5e-5}`` → ``["time.dt=5e-05"]``: each value as TOML text; CaseError for one that has none.

    >>> _override_strings({"time.dt": 5e-5, "fluid": "none", "coupler": {"model": "monolithic", "beta": 1}})
    ['time.dt=5e-05', 'fluid="none"', 'coupler={ model = "monolithic", beta = 1 }']
    """
    out, problems = [], []
    for key, value in values.items():
        try:
            out.append(f"{key}={_toml(value)}")
        except TypeError as exc:
            problems.append(Problem(str(key), value, f"cannot be written as a TOML value ({exc})"))
    if problems:
        raise CaseError(problems)
    return out


_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+$")


def _toml(value: Any) -> str:
    """A Python value as TOML text (for ``key=value`` overrides).

    >>> _toml(True), _toml(3), _toml(0.1), _toml(float("-inf")), _toml('a "b"'), _toml([1, "x"])
    ('true', '3', '0.1', '-inf', '"a \\\\"b\\\\""', '[1, "x"]')
    """
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        number = float(value)
        if math.isnan(number):
            return "nan"
        return repr(number) if math.isfinite(number) else ("inf" if number > 0 else "-inf")
    if isinstance(value, str | os.PathLike):
        return _toml_string(os.fspath(value))
    if isinstance(value, Mapping):
        items = (f"{k if _BARE_KEY.match(str(k)) else _toml_string(str(k))} = {_toml(v)}" for k, v in value.items())
        return "{ " + ", ".join(items) + " }" if value else "{}"
    if isinstance(value, list | tuple | np.ndarray):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    raise TypeError(f"{type(value).__name__} has no TOML form; give a number, boolean, string, list or dict")


def _toml_string(text: str) -> str:
    """A TOML basic string (escapes as TOML has them)."""
    escapes = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f", "\r": "\\r"}
    body = "".join(escapes.get(c, f"\\u{ord(c):04x}" if ord(c) < 0x20 or ord(c) == 0x7F else c) for c in text)
    return f'"{body}"'


# -- results ------------------------------------------------------------------------------------------------
@attrs.frozen(eq=False, repr=False)
class Results:
    """A run's results as arrays: what its results folder holds, or what a run in memory kept.

    Every number is CGS (cm, s, g, dyn/cm²; a tube's flow rates in cm³/s), as the run wrote it: η and
    ``peaks`` in cm (the command line prints µm), pressures in dyn/cm² (the figures show mmHg; 1 mmHg =
    :data:`multilayer.plugin.units.MMHG` dyn/cm²).

    Attributes
    ----------
    summary : dict
        ``summary.json``: ``status``, ``reason``, the resolved ``case`` and
        its ``case_hash``, ``plugins``, ``dofs``, ``steps``, ``t``, ``dt``,
        ``wall_time_s``, ``timings``, ``factorizations``, ``krylov``,
        ``energy.max_relative_residual`` (``docs/case-files.md``, "Results").
    series : dict of str to ndarray
        ``series.csv`` by column, one value per step: ``step``, ``t``, every
        ledger term, ``energy.total``, ``energy.residual``,
        ``energy.relative_residual``, the coupler's diagnostics, every probe
        (NaN where a row has no value).
    probes : dict of str to ndarray
        The probes' columns of ``series``, by probe name.
    eta_lumen : (z, t, eta) or None
        η on the lumen line at every vertex and every step, ``eta[i, j]`` =
        η(t[i], z[j]) (``eta_lumen.csv``); None without a wall.
    folder : Path or None
        The results folder, None for a run held in memory.
    wss_lumen : (z, t, wss) or None
        The wall shear stress τ_w (dyn/cm², positive downstream) at the
        same vertices every step, ``wss[i, j]`` = τ_w(t[i], z[j])
        (``wss_lumen.csv``); None without a fluid.
    """

    summary: dict[str, Any]
    series: dict[str, np.ndarray]
    probes: dict[str, np.ndarray]
    eta_lumen: LumenField | None = None
    folder: Path | None = None
    wss_lumen: LumenField | None = None

    @property
    def status(self) -> str:
        """``ok``, ``failed`` or ``interrupted`` (``running`` for a folder whose run never finished)."""
        return str(self.summary.get("status", ""))

    @property
    def ok(self) -> bool:
        """The run reached its end time."""
        return self.status == "ok"

    @property
    def reason(self) -> str:
        """Why the run stopped, with the time (empty when ok)."""
        return str(self.summary.get("reason", ""))

    @property
    def t(self) -> np.ndarray:
        """The time at the end of every step (s)."""
        return self.series.get("t", np.zeros(0))

    @property
    def steps(self) -> int:
        """The steps done."""
        return int(self.summary.get("steps", len(self.t)))

    @property
    def max_relative_residual(self) -> float:
        """The energy ledger's largest relative residual over the run."""
        return float((self.summary.get("energy") or {}).get("max_relative_residual", math.nan))

    @property
    def peaks(self) -> dict[str, float]:
        """max |η| of every ``eta`` probe, in cm like every number of the API (CGS).

        ``multilayer run`` prints the same peaks in µm: ``1e4 * res.peaks[name]``.
        """
        out = {}
        for p in _probes(self.summary):
            if p.get("quantity") == "eta" and p["name"] in self.series:
                values = np.abs(self.series[p["name"]])
                values = values[~np.isnan(values)]
                out[p["name"]] = max(0.0, float(values.max())) if values.size else 0.0
        return out

    @property
    def cycles(self) -> list[dict[str, Any]] | None:
        """Per complete cycle of a periodic load (``summary.json`` ``cycles``; docs/readouts.md): ``index``,
        ``start``, ``end`` (s); ``pressure`` (name → ``z``, ``systolic``, ``diastolic``, ``mean``, ``pulse`` in
        dyn/cm², the same with ``_mmHg``); ``stroke_volume``; ``distensibility`` (``eta`` probe → ``value``,
        ``per_mmHg``, the areas and the pressure it used); from the second cycle ``change`` (quantity → relative
        change from the cycle before) and ``max_change``.  None when the loads do not repeat."""
        block = self.summary.get("cycles")
        return block.get("cycles") if isinstance(block, dict) else None

    @property
    def period(self) -> float | None:
        """The period of the case's loads (s), None when they do not repeat."""
        block = self.summary.get("cycles")
        return block.get("period") if isinstance(block, dict) else None

    @property
    def wall_shear(self) -> dict[str, Any] | None:
        """``summary.json`` ``wss``: ``z`` (cm), ``peak`` max |τ_w| per position, and with a period ``cycles``, each
        with ``tawss`` (dyn/cm²) and ``osi`` per position and ``change`` (of TAWSS from the cycle before)."""
        block = self.summary.get("wss")
        return block if isinstance(block, dict) else None

    def __repr__(self) -> str:
        where = f", folder={str(self.folder)!r}" if self.folder is not None else ""
        end = f"{self.t[-1]:.6g}" if len(self.t) else "0"
        return (f"Results(status={self.status!r}, steps={self.steps}, t_end={end}, "
                f"probes={list(self.probes)}{where})")


def read_results(folder: str | os.PathLike[str]) -> Results:
    """Read a results folder (``multilayer run --out FOLDER``) back into arrays.

    A failed or interrupted run's folder reads as well: the summary says why,
    the series hold every step done.

    Raises
    ------
    FileNotFoundError
        When ``folder`` holds neither ``summary.json`` nor ``series.csv``.
    ResultsError
        A file of the folder cannot be read: larger than a run ever writes, not JSON, not numbers, a
        snapshot outside the folder (the message names the file).  A run still writing the folder, or
        killed while it did, reads as far as its last whole row.
    """
    _path_arg("read_results", "folder", folder)
    folder = Path(folder)
    if not ((folder / "summary.json").is_file() or (folder / "series.csv").is_file()):
        raise FileNotFoundError(f"{folder} is not a results folder: it has no summary.json or series.csv")
    data = read_run(folder.name, folder)
    geometry = data.case.get("geometry")
    radius = geometry.get("radius") if isinstance(geometry, dict) else None
    eta = lumen_eta(folder, float(radius)) if isinstance(radius, int | float) and radius > 0 else None
    return _results(dict(data.summary), dict(data.series), eta, folder, lumen_wss(folder))


def _probes(summary: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The probes of the summary's resolved case (those with a name: a folder's summary is data)."""
    case = summary.get("case")
    output = case.get("output") if isinstance(case, dict) else None
    probes = output.get("probes") if isinstance(output, dict) else None
    return [p for p in probes if isinstance(p, dict) and isinstance(p.get("name"), str)] \
        if isinstance(probes, list) else []


def _results(summary: dict[str, Any], series: dict[str, np.ndarray], eta: LumenField | None,
             folder: Path | None, wss: LumenField | None = None) -> Results:
    names = [p["name"] for p in _probes(summary)]
    return Results(summary, series, {n: series[n] for n in names if n in series}, eta, folder, wss)


def _held_results(held: HeldResults) -> Results:
    """The Results of a run held in memory: the same arrays a folder would read back."""
    series = held.tables["series.csv"].arrays() if "series.csv" in held.tables else {}
    eta, wss = (lumen_field(held.tables[name].arrays(), name) if name in held.tables else None
                for name in ("eta_lumen.csv", "wss_lumen.csv"))  # as lumen_eta, lumen_wss read the tables
    return _results(held.summary, series, eta, None, wss)


# -- running ------------------------------------------------------------------------------------------------
def run(case: Case, out: str | os.PathLike[str] | None = None, *, checkpoint_every: int = 0,
        progress: bool | Callable[[dict[str, Any]], None] | None = None, registry: Registry | None = None,
        plots: bool = False, force: bool = False) -> Results:
    """Run ``case`` to its end time and return its :class:`Results`.

    Parameters
    ----------
    case : Case
        From :func:`load_case`.
    out : path-like, optional
        A results folder, written exactly as ``multilayer run CASE --out OUT
        --no-plots`` writes it (``summary.json``, ``series.csv``,
        ``eta_lumen.csv``, snapshots every ``output.every`` steps) and read
        back.  Without it the run touches no disk: rows and summary are held
        in memory (no snapshots, no checkpoints) and the Results are the
        same arrays, bit for bit.
    checkpoint_every : int
        With ``out``: write a checkpoint (``checkpoint.json`` + ``.npz``) every so many steps (and when
        interrupted), for ``multilayer resume``.
    progress : bool or callable, optional
        True shows the command line's progress bar (on stderr); a callable
        is called after every step with the step's row (a dict: ``step``,
        ``t``, the ledger, the probes).
    registry : Registry, optional
        The plugins; every installed one by default.
    plots : bool
        With ``out``: also draw the figures, as ``multilayer run`` without
        ``--no-plots`` does.
    force : bool
        With ``out``: write into a folder a run refuses by default (the
        current directory, home, a non-empty folder that is not a results
        folder), as ``multilayer run --force``; the run still touches only
        the files it writes.

    Returns
    -------
    Results
        ``status`` is ``ok``, ``failed`` (``reason`` says where and when; the
        series hold every step done, the one that broke a guard included
        when the energy bound stopped it) or ``interrupted`` (SIGINT or
        SIGTERM: the run finished its step and stopped).  A failed run does
        not raise.

    Raises
    ------
    ArgumentError
        An argument of the wrong type or value (a path where a Case is expected, ``checkpoint_every`` not a
        whole number ≥ 0, ...), or ``checkpoint_every``, ``plots`` or ``force`` without ``out``.
    ResultsError
        When ``out`` cannot be used (not writable, held by another run).

    Examples
    --------
    In a source checkout, with the installed plugins (``tests/test_api.py`` runs these lines)::

        res = run(load_case("cases/membrane-mode.toml", {"time.end": 0.001, "mesh.nz": 16}))
        res.status, len(res.t), res.max_relative_residual < 1e-12     # ('ok', 50, True)
    """
    _case_arg("run", case)
    _path_arg("run", "out", out, optional=True)
    if isinstance(checkpoint_every, bool) or not isinstance(checkpoint_every, int) or checkpoint_every < 0:
        raise ArgumentError(f"run(checkpoint_every=...): expected a whole number ≥ 0 (steps), got {checkpoint_every!r}")
    for name, value in (("plots", plots), ("force", force)):
        if not isinstance(value, bool):
            raise ArgumentError(f"run({name}=...): expected True or False, got {value!r}")
    if not (progress is None or isinstance(progress, bool) or callable(progress)):
        raise ArgumentError(f"run(progress=...): expected True, False, None or a callable, got {progress!r}")
    if out is None and (checkpoint_every or plots or force):
        raise ArgumentError("checkpoints, figures and force need a results folder: give run(case, out=...)")
    registry = registry or Registry.load()
    bar = None
    callback: Callable[[Tally, dict], None] | None = None
    if progress is True:
        from multilayer.runner.progress import ProgressBar

        bar = ProgressBar(case.time.end, enabled=True)
        callback = bar
    elif callable(progress):
        def callback(tally: Tally, row: dict) -> None:
            progress(row)
    try:
        if out is None:
            _, held = run_held(case, registry, progress=callback)
            return _held_results(held)
        result = run_case(case, out, registry, checkpoint_every=checkpoint_every, progress=callback, force=force)
    finally:
        if bar is not None:
            bar.close()
    if plots and result.steps:
        from multilayer.results.figures import plot_run

        plot_run(out)
    return read_results(out)


def steps(case: Case, *, registry: Registry | None = None) -> Generator[Step, None, None]:
    """The steps of a run of ``case``, one at a time, without a results folder.

    Each :class:`~multilayer.runner.stepping.Step` has ``n``, ``t``, ``ledger``
    (every term of the step's energy ledger, ``energy.total``,
    ``energy.residual``, ``energy.relative_residual``), ``probes`` (by name),
    ``diagnostics``, ``row`` (the step's row of ``series.csv``) and
    ``state`` (the :class:`~multilayer.scene.state.State`: every field).
    The numbers are those of :func:`run`, bit for bit.  The scene is built
    when the first step is asked for.

    Stop whenever you like: leaving a ``for`` loop (``break``), or
    ``close()`` on the generator, ends the run; nothing is left behind (no
    file is written; BLAS threads are limited to ``[solver] threads`` only
    while a step is computed).

    Raises
    ------
    RunFailed
        When a guard stops the run (a non-finite value, a wall collapsing or
        blown out, energy beyond the work put in, sub-iterations that do not
        converge, a scene that cannot be set up); the message names the time.

    Examples
    --------
    In a source checkout, with the installed plugins (``tests/test_api.py`` runs these lines)::

        case = load_case("cases/membrane-mode.toml", {"mesh.nz": 16})
        for step in steps(case):
            if step.probes["eta_mid"] < 0.005:      # η at mid-length down to half its start: t ≈ T/6
                break
        step.n, round(step.t, 5), step.ledger["energy.relative_residual"] < 1e-12     # (235, 0.0047, True)
    """
    _case_arg("steps", case)
    registry = registry or Registry.load()
    with blas_threads(case.threads):
        with setting_up():
            setup, coupler = prepare(case, registry)
            state = coupler.initial_state(setup)
        tally = Tally.start(setup, coupler, state)
    probes = setup.probe_rows(case.output.probes)
    limited = _blas_limit(case.threads)
    advancing = iterate_steps(setup, coupler, state, tally, probes)
    try:
        while True:
            with limited():
                try:
                    step = next(advancing)
                except StopIteration:
                    return
                except SchemeFailure as exc:
                    raise RunFailed(str(exc)) from exc
                except (FloatingPointError, np.linalg.LinAlgError) as exc:
                    raise RunFailed(f"{type(exc).__name__} after step {tally.steps} (t = {tally.t:.6g} s): "
                                    f"{exc}") from exc
            yield step
    finally:
        advancing.close()


def _blas_limit(threads: int) -> Callable[[], contextlib.AbstractContextManager]:
    """A context factory limiting BLAS to ``threads`` (0: unchanged), cheap enough to enter every step."""
    if threads <= 0:
        return contextlib.nullcontext
    from threadpoolctl import ThreadpoolController

    controller = ThreadpoolController()  # the libraries are inspected once, not at every step
    return lambda: controller.limit(limits=threads, user_api="blas")
