"""``multilayer stability``: which coupler stays stable as the wall gets light, in one map.

The added-mass effect (Causin, Gerbeau & Nobile 2005) makes partitioned
schemes fail, or iterate more, when the thin layer next to the fluid is light
against the fluid it moves: the ratio ρ₁h/(ρ_f R).  This command runs a grid
of couplers × ratios (× ``--vary`` values, usually Δt) on one scene and says,
for each run, whether it stayed stable, at what cost in iterations and wall
time, or when it failed.

It is a sibling of :mod:`multilayer.campaign.study` and shares its grid
(:mod:`multilayer.campaign.planning`): a ratio is one more axis
(:class:`~multilayer.case.grid.Setting` ``ratio=<r>`` realised as
``layers[L].density = r·ρ_f·R/h``, :meth:`Ratios.axis`), planned by
:func:`~multilayer.campaign.planning.plan_grid`, validated and run by
:func:`~multilayer.campaign.planning.invalid_runs` and
:func:`~multilayer.campaign.planning.run_planned` into ordinary results folders
``OUT/<coupler>/ratio=<r>/<key=value>/...``.  Everything reported is read
back from those folders: :func:`measure_run` makes a run's row,
:func:`map_data` the whole ``stability.json``, and
:mod:`multilayer.campaign.stability_report` the table and the map.

The command line (its options, messages and exit codes) is
:mod:`multilayer.commands.stability`.

The measurements are pure functions of numbers and arrays
(:func:`density_for_ratio`, :func:`mass_ratio`, :func:`initial_energy`,
:func:`energy_excess`, :func:`energy_growth`, :func:`is_stable`,
:func:`iteration_counts`, :func:`failure_time`).  See ``docs/stability.md``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from multilayer.campaign.planning import CouplerChoice, Planned
from multilayer.case.grid import Setting
from multilayer.case.keys import key_steps
from multilayer.case.model import Case
from multilayer.plugin.problems import MISSING, CaseError, Problem
from multilayer.results.reading import RunData

#: a run is stable when its energy growth stays at or below this (relative round-off of the ledger)
GROWTH_TOLERANCE = 1e-9
#: ρ₁h/(ρ_f R) without ``--ratios``
DEFAULT_RATIOS = "1,0.1,0.01,0.001"
#: the grid axis of the ratio (folders ``ratio=<r>``)
RATIO = "ratio"
#: the scale of the energy growth never goes below this (a run with no energy and no work)
TINY = 1e-300
#: verdicts, best first, with their colours in the map
VERDICTS = {"stable": "#43a047", "energy grew": "#fb8c00", "failed": "#e53935"}

# -- measurements (pure) ---------------------------------------------------------


def density_for_ratio(ratio: float, fluid_density: float, radius: float, thickness: float) -> float:
    """The thin layer's density ρ₁ that makes ρ₁h/(ρ_f R) equal ``ratio``: ρ₁ = ratio·ρ_f·R/h.

    Parameters
    ----------
    ratio : float
        ρ₁h/(ρ_f R), > 0.
    fluid_density : float
        ρ_f (g/cm³).
    radius : float
        R, the lumen radius (cm).
    thickness : float
        h, the thin layer's thickness (cm).

    Returns
    -------
    float
        ρ₁ (g/cm³).

    Examples
    --------
    >>> density_for_ratio(0.1, 1.0, 0.5, 0.1)
    0.5
    >>> round(density_for_ratio(0.22, 1.0, 0.5, 0.1), 12)  # pulse-koiter.toml's own wall
    1.1
    """
    return ratio * fluid_density * radius / thickness


def mass_ratio(density: float, thickness: float, fluid_density: float, radius: float) -> float:
    """ρ₁h/(ρ_f R), the thin layer's mass per area over the fluid's across the radius.

    >>> mass_ratio(1.1, 0.1, 1.0, 0.5)
    0.22000000000000003
    >>> mass_ratio(density_for_ratio(1e-3, 1.0, 0.5, 0.1), 0.1, 1.0, 0.5)
    0.001
    """
    return density * thickness / (fluid_density * radius)


def _row_sums(series: Mapping[str, np.ndarray], prefix: str) -> np.ndarray:
    """Per row, the sum of every column whose name starts with ``prefix`` (zeros when there is none)."""
    rows = len(series.get("energy.total", ()))
    columns = [np.asarray(v, dtype=float) for k, v in series.items() if k.startswith(prefix)]
    return np.sum(columns, axis=0) if columns else np.zeros(rows)


def initial_energy(series: Mapping[str, np.ndarray]) -> float | None:
    """E₀, the energy before the first step, from the first row of a ledger.

    The runner closes each step as Eⁿ⁺¹ − Eⁿ − W + D = residual
    (:func:`multilayer.runner.ledger.close`), so E₀ = E₁ − W₁ + D₁ − residual₁
    with W₁ the sum of the ``work.*`` columns and D₁ of the
    ``dissipation.*`` columns of the first row, and residual₁ its
    ``energy.residual`` (0 when the column is missing).  This is the very
    E₀ the runner used, up to round-off.

    Parameters
    ----------
    series : mapping of str to ndarray
        ``series.csv`` by column (:func:`multilayer.results.reading.read_series`).

    Returns
    -------
    float or None
        E₀; None without an ``energy.total`` column or rows.

    Examples
    --------
    >>> initial_energy({"energy.total": np.array([2.5, 3.0]), "work.inlet": np.array([1.0, 1.0]),
    ...                 "dissipation.viscous": np.array([0.25, 0.5]), "energy.residual": np.array([-0.25, 0.0])})
    2.0
    """
    energy = series.get("energy.total")
    if energy is None or not len(energy):
        return None
    residual = series.get("energy.residual", np.zeros(len(energy)))
    return float(energy[0] - _row_sums(series, "work.")[0] + _row_sums(series, "dissipation.")[0] - residual[0])


def energy_excess(series: Mapping[str, np.ndarray]) -> np.ndarray:
    """Eₙ − E₀ − Wₙ per row: how much more energy the run holds than it started with plus the work put in.

    Wₙ is the cumulative sum over the first n rows of every ``work.*``
    column; E₀ is :func:`initial_energy`.  By the ledger this is
    Σₖ (residualₖ − Dₖ): ≤ round-off while the dissipation is ≥ 0.

    Examples
    --------
    >>> energy_excess({"energy.total": np.array([1.0, 1.5, 4.0]), "work.p": np.array([1.0, 1.0, 1.0]),
    ...                "dissipation.v": np.array([0.0, 0.5, 0.5])})
    array([ 0. , -0.5,  1. ])
    """
    energy = series.get("energy.total")
    if energy is None or not len(energy):
        return np.zeros(0)
    return np.asarray(energy, dtype=float) - initial_energy(series) - np.cumsum(_row_sums(series, "work."))


def energy_growth(series: Mapping[str, np.ndarray]) -> float | None:
    """max over the steps of (Eₙ − E₀ − Wₙ) / max(|E₀| + maxₙ |Wₙ|, tiny): > 0 the run made energy.

    Parameters
    ----------
    series : mapping of str to ndarray
        ``series.csv`` by column: ``energy.total``, the ``work.*`` and
        ``dissipation.*`` columns and ``energy.residual``.

    Returns
    -------
    float or None
        The largest relative excess of :func:`energy_excess`; None without
        rows; inf when a value is not finite (a run that blew up).

    Examples
    --------
    A run from rest that takes in 0.5 a step and dissipates 0.1 a step
    stays below the work put in (by 0.1 of it, at best, after step 1):

    >>> calm = {"energy.total": np.array([0.4, 0.8]), "work.inlet": np.array([0.5, 0.5]),
    ...         "dissipation.viscous": np.array([0.1, 0.1])}
    >>> energy_growth(calm)
    -0.09999999999999998

    One that holds 1.2 after taking in 1 is above it, by 0.2 of the work:

    >>> energy_growth({"energy.total": np.array([0.5, 1.2]), "work.inlet": np.array([0.5, 0.5])})
    0.19999999999999996
    """
    excess = energy_excess(series)
    if not len(excess):
        return None
    work = np.cumsum(_row_sums(series, "work."))
    e0 = initial_energy(series)
    if not (np.all(np.isfinite(excess)) and np.all(np.isfinite(work))):
        return math.inf
    scale = max(abs(e0) + float(np.max(np.abs(work))), TINY)
    return float(np.max(excess)) / scale


def is_stable(status: str, growth: float | None, tolerance: float = GROWTH_TOLERANCE) -> bool:
    """A run is stable when it ended ok and its :func:`energy_growth` is at most ``tolerance``.

    ``tolerance`` (1e-9) is the ledger's round-off: every step's identity
    closes to ~1e-13 relative and the tests assert ≤ 1e-9, so a stable
    scheme (dissipation ≥ 0) stays below it over thousands of steps, while
    an instability grows geometrically and passes it within a few steps.

    Examples
    --------
    >>> is_stable("ok", -0.3), is_stable("ok", 2e-10), is_stable("ok", 1e-6)
    (True, True, False)
    >>> is_stable("failed", -0.3), is_stable("ok", None)
    (False, False)
    """
    return status == "ok" and growth is not None and growth <= tolerance


def iteration_counts(series: Mapping[str, np.ndarray]) -> dict[str, Any]:
    """Sub-iterations per step from the ``iterations`` column.

    A coupler without sub-iterations writes no such column: it solves once
    per step, counted as 1 per row with ``reported`` False.

    Returns
    -------
    dict
        ``reported``, ``total``, ``mean``, ``max``; all None but
        ``reported`` without rows.

    Examples
    --------
    >>> iteration_counts({"t": np.array([1.0, 2.0, 3.0]), "iterations": np.array([3.0, 5.0, 4.0])})
    {'reported': True, 'total': 12, 'mean': 4.0, 'max': 5}
    >>> iteration_counts({"t": np.array([1.0, 2.0])})
    {'reported': False, 'total': 2, 'mean': 1.0, 'max': 1}
    """
    column = series.get("iterations")
    if column is None:
        rows = len(series.get("t", ()))
        return {"reported": False, "total": rows if rows else None, "mean": 1.0 if rows else None,
                "max": 1 if rows else None}
    counts = np.asarray(column, dtype=float)
    counts = counts[np.isfinite(counts)]
    if not len(counts):
        return {"reported": True, "total": None, "mean": None, "max": None}
    return {"reported": True, "total": int(counts.sum()), "mean": float(counts.mean()), "max": int(counts.max())}


def failure_time(series: Mapping[str, np.ndarray]) -> float | None:
    """The time of the last row written (s), how far a failed run got; None without rows.

    The runner does not write the row of a step that fails its checks
    (a non-finite value, a collapsing wall), so the failure is in the step
    after this time; the run's ``reason`` names the time it saw.

    >>> failure_time({"t": np.array([1e-4, 2e-4])}), failure_time({})
    (0.0002, None)
    """
    t = series.get("t")
    return float(t[-1]) if t is not None and len(t) else None


# -- the options: ratios, layer, --vary ------------------------------------------


def parse_ratios(text: str) -> list[tuple[str, float]]:
    """``--ratios 1,0.1,...`` → (text, value) pairs; CaseError at ``--ratios`` for anything but distinct numbers > 0.

    >>> parse_ratios("1, 1e-3")
    [('1', 1.0), ('1e-3', 0.001)]
    >>> parse_ratios("1,0,x")
    Traceback (most recent call last):
    ...
    multilayer.plugin.problems.CaseError: --ratios = '0': expected a number > 0 (ρ₁h/(ρ_f R))
    --ratios = 'x': expected a number > 0 (ρ₁h/(ρ_f R))
    """
    problems, out = [], []
    for item in (s.strip() for s in text.split(",")):
        try:
            value = float(item)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and value > 0):
            problems.append(Problem("--ratios", item, "expected a number > 0 (ρ₁h/(ρ_f R))"))
        elif value in (v for _, v in out):
            problems.append(Problem("--ratios", item, "given twice"))
        else:
            out.append((item, value))
    if problems:
        raise CaseError(problems)
    return out


def layer_problems(case: Case, layer: int) -> list[Problem]:
    """What keeps ``layers[layer]`` of ``case`` from carrying the ratio: it must exist, be thin and have h and ρ₁."""
    if case.fluid is None:
        return [Problem("fluid", MISSING, "the mass ratio ρ₁h/(ρ_f R) needs a fluid; the case has none")]
    thin = [f"layers[{i}] ({s.model})" for i, s in enumerate(case.layers) if s.thin]
    hint = "thin layers here: " + ", ".join(thin) if thin else "the case has no thin layer"
    if not 0 <= layer < len(case.layers):
        return [Problem("--layer", layer, f"expected a layer index 0..{len(case.layers) - 1}" if case.layers
                        else "the case has no layers", hint)]
    spec = case.layers[layer]
    if not spec.thin:
        return [Problem("--layer", layer, f"layers[{layer}] is a thick layer ({spec.model}); the ratio "
                        "ρ₁h/(ρ_f R) is that of a thin layer", hint)]
    return [Problem(f"layers[{layer}].{key}", MISSING, f"the ratio ρ₁h/(ρ_f R) needs the thin layer's {key}")
            for key in ("thickness", "density") if not isinstance(spec.params.get(key), int | float)]


def _density_keys(layer: int) -> list[list[str | int]]:
    return [["fluid", "density"], ["geometry", "radius"], ["layers", layer, "thickness"], ["layers", layer, "density"]]


def vary_problems(axes: Sequence[tuple[str, Sequence[str]]], layer: int) -> list[Problem]:
    """A ``--vary`` key that enters ρ₁ = ratio·ρ_f·R/h (or holds it) would break the ratios: a problem each.

    >>> [str(p) for p in vary_problems([("time.dt", ["1", "2"]), ("geometry.radius", ["1", "2"])], 0)]
    ["--vary = 'geometry.radius=1,2': the ratios set layers[0].density from fluid.density, geometry.radius and \
layers[0].thickness; change those with --set"]
    """
    out = []
    for key, values in axes:
        steps = key_steps(key) or []
        if any(target[:len(steps)] == steps for target in _density_keys(layer)):
            out.append(Problem("--vary", f"{key}={','.join(values)}", f"the ratios set layers[{layer}].density "
                               f"from fluid.density, geometry.radius and layers[{layer}].thickness; change those "
                               "with --set"))
    return out


@attrs.frozen
class Ratios:
    """The ratios of a map and how they are realised on one case."""

    layer: int
    model: str
    thickness: float  #: h (cm)
    fluid_density: float  #: ρ_f (g/cm³)
    radius: float  #: R (cm)
    values: tuple[tuple[str, float], ...]  #: (as given, value)

    @classmethod
    def of(cls, case: Case, layer: int, values: Sequence[tuple[str, float]]) -> Ratios:
        spec = case.layers[layer]
        return cls(layer, spec.model, float(spec.params["thickness"]), float(case.fluid.params["density"]),
                   case.geometry.radius, tuple(values))

    def density(self, ratio: float) -> float:
        return density_for_ratio(ratio, self.fluid_density, self.radius, self.thickness)

    def axis(self) -> list[Setting]:
        """The grid axis: ``ratio=<r>`` set as ``layers[L].density=<ρ₁>``."""
        return [Setting(RATIO, text, f"layers[{self.layer}].density={self.density(value)!r}")
                for text, value in self.values]

    def describe(self) -> dict[str, Any]:
        return {"layer": {"index": self.layer, "path": f"layers[{self.layer}]", "model": self.model,
                          "thickness": self.thickness},
                "fluid_density": self.fluid_density, "radius": self.radius,
                "ratios": [{"text": text, "ratio": value, "density": self.density(value)}
                           for text, value in self.values]}


# -- collecting --------------------------------------------------------------------


def _layer_value(case: Mapping[str, Any], layer: int, key: str) -> Any:
    layers = case.get("layers") or []
    return layers[layer].get(key) if layer < len(layers) else None


def measure_run(planned: Planned, run: RunData, layer: int) -> dict[str, Any]:
    """One run's row of ``stability.json``, from its own ``summary.json`` and ``series.csv``."""
    s, case, series = run.summary, run.case, run.series
    values = dict(planned.values)
    time = case.get("time") or {}
    status = s.get("status", "failed")
    density, thickness = _layer_value(case, layer, "density"), _layer_value(case, layer, "thickness")
    fluid_density = (case.get("fluid") or {}).get("density")
    radius = (case.get("geometry") or {}).get("radius")
    known = all(isinstance(v, int | float) for v in (density, thickness, fluid_density, radius))
    growth = energy_growth(series)
    excess = energy_excess(series)
    peak = int(np.argmax(excess)) if len(excess) and np.all(np.isfinite(excess)) else None
    return {
        "label": planned.label,
        "folder": planned.folder,
        "coupler": planned.coupler,
        "model": (case.get("coupler") or {}).get("model"),
        "ratio": float(values.pop(RATIO)),
        "values": values,
        "overrides": list(planned.variant.overrides),
        "density": density,
        "ratio_realised": mass_ratio(density, thickness, fluid_density, radius) if known else None,
        "dt": time.get("dt"),
        "status": status,
        "reason": s.get("reason", "" if s else "no summary.json written"),
        "failure_time_s": failure_time(series) if status != "ok" else None,
        "steps": s.get("steps"),
        "steps_planned": round(time["end"] / time["dt"]) if time.get("end") and time.get("dt") else None,
        "iterations": iteration_counts(series),
        "wall_time_s": s.get("wall_time_s"),
        "energy_initial": initial_energy(series),
        "energy_growth": growth,
        "energy_growth_time_s": float(series["t"][peak]) if peak is not None and "t" in series else None,
        "stable": is_stable(status, growth),
        "verdict": verdict(status, growth),
    }


def verdict(status: str, growth: float | None) -> str:
    """``stable``, ``energy grew`` (ended ok, :func:`is_stable` false) or ``failed``.

    >>> verdict("ok", -1.0), verdict("ok", 1e-3), verdict("failed", -1.0)
    ('stable', 'energy grew', 'failed')
    """
    if status != "ok":
        return "failed"
    return "stable" if is_stable(status, growth) else "energy grew"


def map_data(planned: Sequence[Planned], runs: Mapping[str, RunData], ratios: Ratios,
             couplers: Sequence[CouplerChoice], axes: Sequence[tuple[str, Sequence[str]]], *, command: str,
             case_file: Path, title: str, overrides: Sequence[str]) -> dict[str, Any]:
    """The whole of ``stability.json``: what was asked, how the ratios are realised, one row per run."""
    return {
        "command": command,
        "case_file": str(case_file),
        "title": title,
        "overrides": list(overrides),
        **ratios.describe(),
        "couplers": [attrs.asdict(c) for c in couplers],
        "vary": [{"key": k, "values": v} for k, v in axes],
        "tolerance": GROWTH_TOLERANCE,
        "runs": [measure_run(p, runs[p.label], ratios.layer) for p in planned],
    }
