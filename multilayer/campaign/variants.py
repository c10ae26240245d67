"""Variants of one scene: case files with overrides, from files or from ``--vary``.

A variant is a case file plus overrides.  Several case files give one
variant each; one case file with ``--vary KEY=A,B,...`` gives one variant per
value, each value read exactly like a ``--set`` value (a whole inline table
included, so a layer can change model together with its parameters).
"""

from __future__ import annotations

import re
import traceback
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs

from multilayer.case.casefile import load_case
from multilayer.case.keys import key_steps, parse_value, parse_vary
from multilayer.plugin.problems import CaseError, Problem
from multilayer.plugin.registry import Registry
from multilayer.runner.loop import RunResult, run_case

#: snapshots per run when a case writes none (the space–time plot needs them)
SNAPSHOTS = 100


@attrs.frozen
class Variant:
    """One column of the comparison: a case file, its overrides, its results folder name."""

    label: str
    case_file: Path
    overrides: tuple[str, ...] = ()


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


#: keys whose value is a whole plugin table (``coupler = "monolithic"`` names its model, as ``{model = ...}`` does)
MODEL_KEYS = ("fluid", "coupler", "model")


def vary_labels(key: str, texts: Sequence[str]) -> list[str]:
    """One label per ``--vary`` value, alike for alike values: a model by its name (a bare name for a plugin
    table, or a table's ``model``, followed by the table's keys that differ between the values when the name
    alone repeats), any other value as ``<last key>=<value>``.

    >>> vary_labels("layers[0].tension", ["2e4", "8e4"])
    ['tension=2e4', 'tension=8e4']
    >>> vary_labels("coupler", ['kinematic-splitting', '{model="monolithic", scheme="bdf2"}'])
    ['kinematic-splitting', 'monolithic']
    >>> vary_labels("coupler", ['{model="monolithic", scheme="bdf2"}', '{model="monolithic", scheme="crank-nicolson"}'])
    ['monolithic+scheme=bdf2', 'monolithic+scheme=crank-nicolson']
    """
    steps = key_steps(key)
    names = [s for s in steps if isinstance(s, str)]
    whole_table = isinstance(steps[-1], int) or names[-1] in MODEL_KEYS
    values = [parse_value(text) for text in texts]
    tables = [v for v in values if isinstance(v, Mapping)]
    labels = []
    for text, value in zip(texts, values):
        if isinstance(value, Mapping):
            model = str(value.get("model", names[-1]))
            if sum(str(t.get("model", names[-1])) == model for t in tables) > 1:
                same = [t for t in tables if str(t.get("model", names[-1])) == model]
                differ = [k for k in value if k != "model" and any(t.get(k) != value[k] for t in same)]
                model = "+".join([model, *(f"{k}={value[k]}" for k in differ)])
            labels.append(sanitize(model))
        elif whole_table and isinstance(value, str):
            labels.append(sanitize(value))
        else:
            labels.append(sanitize(f"{names[-1]}={text}"))
    return labels


def make_variants(case_files: Sequence[Path], vary: str | None = None, overrides: Sequence[str] = ()) -> list[Variant]:
    """The variants of a comparison (one case file alone is one variant); CaseError when ``--vary`` is malformed.

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
        labels = unique(vary_labels(key, values))
        return [Variant(label, files[0], (*overrides, f"{key}={v}")) for label, v in zip(labels, values)]
    if not files:
        raise CaseError([Problem("compare", [], "expected one or more case files")])
    labels = unique([sanitize(f.stem) for f in files])
    return [Variant(label, f, tuple(overrides)) for label, f in zip(labels, files)]


def load_variants(
    variants: Sequence[Variant], registry: Registry, snapshots: bool = True
) -> tuple[list[tuple[Variant, Any]], dict[str, list[Problem]]]:
    """Validate every variant: ((variant, case) pairs, problems by label).

    With ``snapshots`` (compare's space–time plot of η reads the wall
    snapshots), a case that writes none (``output.every = 0``) gets
    ``output.every = max(1, steps // 100)`` added to its overrides.
    """
    loaded, invalid = [], {}
    for variant in variants:
        try:
            case = load_case(variant.case_file, variant.overrides, registry)
            if snapshots and case.output.every == 0:
                variant = attrs.evolve(variant, overrides=(
                    *variant.overrides, f"output.every={max(1, case.time.steps // SNAPSHOTS)}"))
                case = load_case(variant.case_file, variant.overrides, registry)
        except CaseError as exc:
            invalid[variant.label] = exc.problems
            continue
        loaded.append((variant, case))
    return loaded, invalid


def invalid_message(command: str, variants: Sequence[Variant], invalid: Mapping[str, Sequence[Problem]],
                    noun: str = "variants") -> str:
    """What :func:`load_variants` found wrong: a count, then each problem prefixed by its variant's label.

    >>> v = [Variant("a", Path("m.toml")), Variant("b", Path("m.toml"))]
    >>> print(invalid_message("compare", v, {"b": [Problem("time.dt", -1, "expected a number > 0")]}))
    compare: 1 of 2 variants invalid
    b: time.dt = -1: expected a number > 0
    """
    lines = [f"{command}: {len(invalid)} of {len(variants)} {noun} invalid"]
    lines += [f"{v.label}: {problem}" for v in variants for problem in invalid.get(v.label, [])]
    return "\n".join(lines)


def run_variant(case: Any, folder: Path, registry: Registry) -> RunResult:
    """Run a validated case into ``folder``: its result (``status``, ``reason``, the ``signal`` that stopped it).

    A run that raises (a bug, not a failed run) is printed with its
    traceback and returned as failed, so the other variants still run.
    """
    try:
        return run_case(case, folder, registry)
    except Exception as exc:  # keep the other variants; the traceback says where
        traceback.print_exc()
        return RunResult("failed", f"{type(exc).__name__}: {exc}", folder)
