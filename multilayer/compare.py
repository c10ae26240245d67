"""``multilayer compare``: variants of one scene, run side by side and measured alike.

A variant is a case file with overrides.  Several case files give one
variant each; one case file with ``--vary KEY=A,B,...`` gives one variant
per value, each value read exactly like a ``--set`` value (a whole inline
table included, so a layer can change model together with its parameters).
Every variant runs into ``OUT/<label>/``, an ordinary results folder (see
:mod:`multilayer.run`), and the comparison is then made from those folders
alone — ``summary.json``, ``series.csv`` and the wall snapshots — so every
number of ``report.md`` / ``report.json`` can be recomputed from the runs'
own files.  See ``docs/compare.md``.
"""

from __future__ import annotations

import csv
import json
import math
import re
import sys
import traceback
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs
import meshio
import numpy as np

from multilayer.casefile import key_steps, load_case, parse_value
from multilayer.cli import FAILED, INVALID, OK
from multilayer.problems import CaseError, Problem
from multilayer.registry import Registry
#: snapshots per run when a case writes none (the space–time plot needs them)
SNAPSHOTS = 100


# -- variants ----------------------------------------------------------------


@attrs.frozen
class Variant:
    """One column of the comparison: a case file, its overrides, its results folder name."""

    label: str
    case_file: Path
    overrides: tuple[str, ...] = ()


def split_values(text: str) -> list[str]:
    """Split ``text`` on the commas outside braces, brackets and TOML strings.

    >>> split_values('2e4, 8e4')
    ['2e4', '8e4']
    >>> split_values('{model="a",x=[1,2]},"b,c"')
    ['{model="a",x=[1,2]}', '"b,c"']
    >>> split_values('{model="a"')
    Traceback (most recent call last):
    ...
    ValueError: unbalanced '{': no closing '}'
    """
    closing = {"{": "}", "[": "]"}
    values, stack, quote, start, i = [], [], "", 0, 0
    while i < len(text):
        c = text[i]
        if quote:
            if c == "\\" and quote == '"':
                i += 1  # an escaped character cannot end the string
            elif c == quote:
                quote = ""
        elif c in "\"'":
            quote = c
        elif c in closing:
            stack.append(c)
        elif c in "}]":
            if not stack or closing[stack[-1]] != c:
                raise ValueError(f"unbalanced {c!r} at character {i + 1}")
            stack.pop()
        elif c == "," and not stack:
            values.append(text[start:i].strip())
            start = i + 1
        i += 1
    if quote:
        raise ValueError(f"unterminated string: no closing {quote}")
    if stack:
        raise ValueError(f"unbalanced {stack[-1]!r}: no closing {closing[stack[-1]]!r}")
    values.append(text[start:].strip())
    return values


def parse_vary(text: str) -> tuple[str, list[str]]:
    """``KEY=A,B,...`` → (KEY, [A, B, ...]); CaseError at ``--vary`` when malformed.

    >>> parse_vary("layers[0].tension=2e4,8e4")
    ('layers[0].tension', ['2e4', '8e4'])
    >>> parse_vary("tension")
    Traceback (most recent call last):
    ...
    multilayer.problems.CaseError: --vary = 'tension': expected KEY=A,B[,C...] with KEY like time.dt or layers[0].young
    """
    key, eq, rest = text.partition("=")
    key = key.strip()
    if not eq or not key_steps(key):
        raise CaseError([Problem("--vary", text, "expected KEY=A,B[,C...] with KEY like time.dt or layers[0].young")])
    try:
        values = split_values(rest)
    except ValueError as exc:
        raise CaseError([Problem("--vary", text, f"cannot split the values: {exc}")]) from None
    if any(not v for v in values):
        raise CaseError([Problem("--vary", text, "an empty value", "two commas in a row, or one at an end?")])
    if len(values) < 2:
        raise CaseError([Problem("--vary", text, "expected two or more values, separated by commas")])
    return key, values


def sanitize(text: str) -> str:
    """A folder name from free text: letters, digits and ``._+=-`` only, never a leading dash.

    >>> sanitize("tension=2e4"), sanitize("a b/c"), sanitize("-1e9"), sanitize("{}")
    ('tension=2e4', 'a_b_c', '1e9', 'variant')
    """
    name = re.sub(r"[^A-Za-z0-9._+=-]+", "_", text).strip("_.-")
    return name[:48] or "variant"


def unique(labels: Sequence[str]) -> list[str]:
    """The labels, a repeated one suffixed ``-2``, ``-3``, ...

    >>> unique(["a", "b", "a", "a"])
    ['a', 'b', 'a-2', 'a-3']
    """
    out: list[str] = []
    for label in labels:
        name, n = label, 1
        while name in out:
            n += 1
            name = f"{label}-{n}"
        out.append(name)
    return out


def _vary_label(key: str, text: str) -> str:
    value = parse_value(text)
    if isinstance(value, Mapping):
        return sanitize(str(value.get("model", key)))
    tail = [s for s in key_steps(key) if isinstance(s, str)][-1]
    return sanitize(f"{tail}={text}")


def make_variants(case_files: Sequence[Path], vary: str | None = None, overrides: Sequence[str] = ()) -> list[Variant]:
    """The variants of a comparison; CaseError when there are fewer than two or ``--vary`` is malformed.

    ``overrides`` (``--set``) apply to every variant, the varied value last.

    >>> [v.label for v in make_variants([Path("m.toml")], "layers[0].tension=2e4,8e4")]
    ['tension=2e4', 'tension=8e4']
    >>> [v.label for v in make_variants([Path("a/m.toml"), Path("b/m.toml")])]
    ['m', 'm-2']
    """
    files = [Path(f) for f in case_files]
    if vary is not None:
        key, values = parse_vary(vary)
        if len(files) != 1:
            raise CaseError([Problem("--vary", vary, f"varies one case file; got {len(files)}")])
        labels = unique([_vary_label(key, v) for v in values])
        return [Variant(label, files[0], (*overrides, f"{key}={v}")) for label, v in zip(labels, values)]
    if len(files) < 2:
        raise CaseError([Problem("compare", [str(f) for f in files], "expected two or more case files, "
                                 "or one with --vary KEY=A,B")])
    labels = unique([sanitize(f.stem) for f in files])
    return [Variant(label, f, tuple(overrides)) for label, f in zip(labels, files)]


def load_variants(
    variants: Sequence[Variant], registry: Registry
) -> tuple[list[tuple[Variant, Any]], dict[str, list[Problem]]]:
    """Validate every variant: ((variant, case) pairs, problems by label).

    A case that writes no snapshots (``output.every = 0``) gets
    ``output.every = max(1, steps // 100)`` added to its overrides: the
    space–time plot of η reads the wall snapshots.
    """
    loaded, invalid = [], {}
    for variant in variants:
        try:
            case = load_case(variant.case_file, variant.overrides, registry)
            if case.output.every == 0:
                variant = attrs.evolve(variant, overrides=(
                    *variant.overrides, f"output.every={max(1, case.time.steps // SNAPSHOTS)}"))
                case = load_case(variant.case_file, variant.overrides, registry)
        except CaseError as exc:
            invalid[variant.label] = exc.problems
            continue
        loaded.append((variant, case))
    return loaded, invalid


# -- reading a results folder --------------------------------------------------


@attrs.frozen(eq=False)
class RunData:
    """What a results folder holds, read back."""

    label: str
    folder: Path
    summary: Mapping[str, Any]
    series: Mapping[str, np.ndarray]  #: column → values, one per step (NaN where empty)

    @property
    def case(self) -> Mapping[str, Any]:
        """The resolved case of ``summary.json`` ({} if there is none)."""
        return self.summary.get("case") or {}

    @property
    def probes(self) -> list[Mapping[str, Any]]:
        """The probes of the resolved case that have a column in ``series.csv``."""
        return [p for p in (self.case.get("output") or {}).get("probes", []) if p["name"] in self.series]

    @property
    def t(self) -> np.ndarray:
        return self.series.get("t", np.zeros(0))


def read_series(path: Path) -> dict[str, np.ndarray]:
    """``series.csv`` as column → float array; {} when the file is missing."""
    if not path.is_file():
        return {}
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        return {}
    columns, body = rows[0], rows[1:]
    return {c: np.array([float(r[i]) if i < len(r) and r[i] != "" else math.nan for r in body])
            for i, c in enumerate(columns)}


def read_run(label: str, folder: Path) -> RunData:
    """The summary and series of the results folder ``folder`` (empty parts when missing)."""
    summary_path = folder / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.is_file() else {}
    return RunData(label, folder, summary, read_series(folder / "series.csv"))


def lumen_eta(folder: Path, radius: float, part: str = "wall") -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """η(z, t) on the lumen line from the ``<part>_*.vtu`` snapshots listed in ``<part>.pvd``.

    Returns (z, t, eta) with ``eta[i, j]`` = η(t[i], z[j]): the radial
    displacement of the snapshot points at r = R (reference coordinates),
    sorted by z.  None when there are no snapshots.
    """
    pvd = folder / f"{part}.pvd"
    if not pvd.is_file():
        return None
    times, rows, z = [], [], None
    for dataset in ET.parse(pvd).getroot().iter("DataSet"):
        mesh = meshio.read(folder / dataset.get("file"))
        on_lumen = np.isclose(mesh.points[:, 1], radius, rtol=0.0, atol=1e-9 * radius)
        order = np.argsort(mesh.points[on_lumen, 0], kind="stable")
        z = mesh.points[on_lumen, 0][order]
        rows.append(mesh.point_data["displacement"][on_lumen, 1][order])
        times.append(float(dataset.get("timestep")))
    if not rows:
        return None
    return z, np.array(times), np.array(rows)


# -- measures ----------------------------------------------------------------


def max_abs_difference(t_a: np.ndarray, y_a: np.ndarray, t_b: np.ndarray, y_b: np.ndarray) -> float | None:
    """max |y_a − y_b| of the two piecewise-linear series over their common time span.

    Both are evaluated on the union of their times inside the span, which
    holds every kink of either, so this is the exact maximum of the
    difference of the linear interpolants (and the plain max |Δ| on a
    shared time grid).  None when the spans do not overlap.

    >>> t = np.array([0.0, 1.0, 2.0])
    >>> max_abs_difference(t, np.array([0.0, 1.0, 0.0]), np.array([0.0, 2.0]), np.array([0.0, 0.0]))
    1.0
    """
    a, b = _finite(t_a, y_a), _finite(t_b, y_b)
    if not len(a[0]) or not len(b[0]):
        return None
    lo, hi = max(a[0][0], b[0][0]), min(a[0][-1], b[0][-1])
    if lo > hi:
        return None
    grid = np.union1d(a[0], b[0])
    grid = grid[(grid >= lo) & (grid <= hi)]
    return float(np.max(np.abs(np.interp(grid, *a) - np.interp(grid, *b))))


def _finite(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    keep = np.isfinite(t) & np.isfinite(y)
    return np.asarray(t)[keep], np.asarray(y)[keep]


def arrival(t: np.ndarray, y: np.ndarray) -> dict[str, Any]:
    """The pulse at a probe: ``peak`` max |y|, ``peak_time`` its (first) time,
    ``half_peak_time`` the first time |y| reaches half the peak (linear between
    rows), and ``peaked``: False when the peak is on the last row — the pulse
    may still be rising there, so neither time is an arrival yet.

    >>> arrival(np.array([1.0, 2.0, 3.0, 4.0]), np.array([0.0, 1.0, 4.0, -2.0]))
    {'peak': 4.0, 'peak_time': 3.0, 'half_peak_time': 2.3333333333333335, 'peaked': True}
    """
    t, y = _finite(t, y)
    a = np.abs(y)
    if not len(a) or a.max() == 0.0:
        return {"peak": None, "peak_time": None, "half_peak_time": None, "peaked": False}
    i_peak = int(np.argmax(a))
    half = 0.5 * a[i_peak]
    i = int(np.argmax(a >= half))
    t_half = t[i] if i == 0 else t[i - 1] + (half - a[i - 1]) / (a[i] - a[i - 1]) * (t[i] - t[i - 1])
    return {"peak": float(a[i_peak]), "peak_time": float(t[i_peak]), "half_peak_time": float(t_half),
            "peaked": i_peak < len(a) - 1}


def wave_speed(z: Sequence[float], times: Sequence[float | None]) -> float | None:
    """Least-squares slope of z against arrival time (cm/s); None below two distinct times.

    >>> wave_speed([1.0, 2.0, 4.0], [0.001, 0.002, 0.004])
    1000.0
    """
    pairs = [(zi, ti) for zi, ti in zip(z, times) if ti is not None]
    if len(pairs) < 2:
        return None
    zs, ts = np.array(pairs, dtype=float).T
    dt = ts - ts.mean()
    if not np.any(dt):
        return None
    return float(np.sum(dt * (zs - zs.mean())) / np.sum(dt * dt))


def long_wave_speeds(case: Mapping[str, Any], registry: Registry) -> dict[str, float | None]:
    """√(R·C0/ρ_f), and √(R·C0/(ρ_f + ρ₁h/R)) with the wall's inertia (SCHEME §7).

    C0 is the ``long_wave_stiffness(radius=R)`` of the first thin layer,
    built by its plugin's factory from the resolved case.  None without a
    fluid, a thin layer, or with C0 = 0 (a wave membrane).
    """
    none = {"long_wave_speed": None, "long_wave_speed_inertia": None}
    fluid, radius = case.get("fluid"), (case.get("geometry") or {}).get("radius")
    if not fluid or radius is None:
        return none
    for spec in case.get("layers") or []:
        found = registry.find("layer", spec.get("model", ""))
        if found is None or not found.record.thin:
            continue
        try:
            layer = found.record.factory(**{k: v for k, v in spec.items() if k not in ("model", "cells")})
            c0 = float(layer.long_wave_stiffness(radius=radius))
        except (TypeError, ValueError):
            return none
        if c0 <= 0.0:
            return none
        rho = float(fluid["density"])
        surface = getattr(layer, "density", 0.0) * getattr(layer, "thickness", 0.0) / radius
        return {"long_wave_speed": math.sqrt(radius * c0 / rho),
                "long_wave_speed_inertia": math.sqrt(radius * c0 / (rho + surface)) if surface else None}
    return none


def measure(run: RunData, reference: RunData | None, registry: Registry) -> dict[str, Any]:
    """Every number of one report column, from the run's own files.

    Differences are against ``reference`` (None for the reference itself),
    at the ``eta`` probes both runs have (same name).
    """
    s, series = run.summary, run.series
    dofs = {k: v for k, v in (s.get("dofs") or {}).items() if k != "wall_free"}
    probes = {}
    for p in run.probes:
        entry = {"quantity": p["quantity"], "z": p["z"], "r": p.get("r"), "line": p.get("line")}
        if p["quantity"] == "eta":
            entry.update(arrival(run.t, series[p["name"]]))
            if reference is not None:
                other = next((q for q in reference.probes if q["name"] == p["name"] and q["quantity"] == "eta"), None)
                entry["max_abs_diff"] = None if other is None else max_abs_difference(
                    run.t, series[p["name"]], reference.t, reference.series[p["name"]])
        probes[p["name"]] = entry
    # the speed is fitted to the arrivals the series has seen whole
    lumen = {n: e for n, e in probes.items() if e["quantity"] == "eta" and not e["line"] and e["peaked"]}
    pressures = [(float(np.nanmax(series[n])), n) for n, e in probes.items()
                 if e["quantity"] == "p" and np.isfinite(series[n]).any()]
    peak_pressure, peak_pressure_probe = max(pressures) if pressures else (None, None)
    energy = series.get("energy.total", np.zeros(0))
    residual = series.get("energy.relative_residual", np.zeros(0))
    return {
        "label": run.label,
        "out": run.folder.name,
        "status": s.get("status", "failed"),
        "reason": s.get("reason", "" if s else "no summary.json written"),
        "dofs": dofs,
        "dofs_total": sum(dofs.values()) if dofs else None,
        "steps": s.get("steps"),
        "wall_time_s": s.get("wall_time_s"),
        "probes": probes,
        "wave_speed_peak": wave_speed([e["z"] for e in lumen.values()], [e["peak_time"] for e in lumen.values()]),
        "wave_speed_half_peak": wave_speed([e["z"] for e in lumen.values()],
                                           [e["half_peak_time"] for e in lumen.values()]),
        **long_wave_speeds(run.case, registry),
        "peak_pressure": peak_pressure,
        "peak_pressure_probe": peak_pressure_probe,
        "final_energy": float(energy[-1]) if len(energy) else None,
        "max_relative_residual": float(np.nanmax(np.abs(residual))) if len(residual) else None,
    }


def compare_runs(runs: Sequence[RunData], registry: Registry) -> list[dict[str, Any]]:
    """One :func:`measure` per run, the first run the reference of the differences."""
    return [measure(run, runs[0] if i else None, registry) for i, run in enumerate(runs)]


# -- the command -------------------------------------------------------------


def run_variants(loaded: Sequence[tuple[Variant, Any]], out: Path, registry: Registry,
                 log: Callable[[str], None] = print) -> list[RunData]:
    """Run every variant into ``out/<label>/`` and read the folders back.

    A run that raises (a bug, not a failed run) is logged with its traceback
    and kept as a failed variant.
    """
    from multilayer.run import run_case

    runs = []
    for i, (variant, case) in enumerate(loaded, start=1):
        folder = out / variant.label
        try:
            result = run_case(case, folder, registry)
            status, reason = result.status, result.reason
        except Exception as exc:  # keep the other variants; the traceback says where
            traceback.print_exc()
            status, reason = "failed", f"{type(exc).__name__}: {exc}"
        run = read_run(variant.label, folder)
        if run.summary.get("status") != status:
            run = attrs.evolve(run, summary={**run.summary, "status": status, "reason": reason})
        log(f"[{i}/{len(loaded)}] {variant.label}: {status}" + (f" ({reason})" if reason else ""))
        runs.append(run)
    return runs


def write_report(out: Path, variants: Sequence[Variant], runs: Sequence[RunData], registry: Registry,
                 vary: str | None = None) -> dict[str, Any]:
    """``report.json``, ``report.md``, ``probes.png`` and ``eta_spacetime.png`` in ``out``."""
    from multilayer import report

    columns = compare_runs(runs, registry)
    for column, variant in zip(columns, variants):
        column["case_file"] = str(variant.case_file)
        column["overrides"] = list(variant.overrides)
    first = runs[0].case
    data = {
        "title": first.get("title", ""),
        "vary": vary,
        "reference": runs[0].label,
        "variants": columns,
    }
    (out / "report.json").write_text(json.dumps(_without_nan(data), indent=2, allow_nan=False) + "\n")
    report.plot_probes(runs, out / "probes.png")
    radius = (first.get("geometry") or {}).get("radius")
    fields = {run.label: lumen_eta(run.folder, radius) for run in runs} if radius else {}
    report.plot_spacetime(fields, out / "eta_spacetime.png")
    (out / "report.md").write_text(report.markdown(data))
    return data


def _without_nan(value: Any) -> Any:
    """JSON has no NaN: a non-finite number becomes null."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Mapping):
        return {k: _without_nan(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_without_nan(v) for v in value]
    return value


def main(case_files: Sequence[Path], out: Path, vary: str | None, overrides: Sequence[str],
         registry: Registry) -> int:
    """``multilayer compare``: 0 all ran, 1 a variant failed, 2 a variant (or --vary) is invalid."""
    try:
        variants = make_variants(case_files, vary, overrides)
    except CaseError as exc:
        print("compare: invalid command line", file=sys.stderr)
        print(str(exc), file=sys.stderr)
        return INVALID
    loaded, invalid = load_variants(variants, registry)
    if invalid:
        print(f"compare: {len(invalid)} of {len(variants)} variants invalid", file=sys.stderr)
        for variant in variants:
            for problem in invalid.get(variant.label, []):
                print(f"{variant.label}: {problem}", file=sys.stderr)
        return INVALID
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    variants = [v for v, _ in loaded]  # with the snapshot cadence they ran with
    runs = run_variants(loaded, out, registry)
    data = write_report(out, variants, runs, registry, vary)
    failed = [c["label"] for c in data["variants"] if c["status"] != "ok"]
    print(f"report: {out / 'report.md'}")
    if failed:
        print(f"compare: {len(failed)} variant(s) failed: {', '.join(failed)}", file=sys.stderr)
        return FAILED
    return OK
