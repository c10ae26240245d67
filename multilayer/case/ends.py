"""The open ends of the fluid in a case file: each end's condition, looked up in the registry and built.

An end is written as a number (a constant pressure), a string (a pressure
formula in t) or a table ``{kind = "<boundary condition>", ...}`` under
``[loads] inlet`` / ``outlet``.  The kind is a boundary plugin
(``multilayer plugins``); its parameters are checked against the plugin's
schema, then its factory builds the condition (the factory's own verdict
on the values comes back as problems at the end's key path).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from multilayer.boundary.contract import BoundaryCondition, BuildContext
from multilayer.plugin.problems import (
    MISSING,
    CaseError,
    Problem,
    check_params,
    did_you_mean,
)
from multilayer.plugin.registry import Registry
from multilayer.wall.checks import abstract_problem, raised

#: the open ends of the fluid, as keys of ``[loads]``
END_KEYS = ("inlet", "outlet")


def end_kind(spec: Any, path: str) -> tuple[str | None, list[Problem]]:
    """The boundary-condition kind a case-file value names: a number is ``constant``, a string ``formula``."""
    if isinstance(spec, int | float) and not isinstance(spec, bool):
        if not math.isfinite(spec):
            return None, [Problem(path, spec, "expected a finite pressure (dyn/cm²)")]
        return "constant", []
    if isinstance(spec, str):
        return "formula", []
    if not isinstance(spec, Mapping):
        return None, [Problem(path, spec, "expected a number, a formula in t or a table {kind = ...}")]
    kind = spec.get("kind", MISSING)
    if not isinstance(kind, str):
        expected = "missing; expected a boundary condition kind" if kind is MISSING else "expected a kind's name"
        return None, [Problem(f"{path}.kind", kind, expected)]
    return kind, []


def build_end(spec: Any, path: str, registry: Registry, base_dir: Path | str = ".",
              constants: Mapping[str, float] | None = None, end: float = 1.0
              ) -> tuple[BoundaryCondition, dict[str, Any]]:
    """The condition of one end and its resolved case-file data (defaults filled).

    Raises
    ------
    CaseError
        With every problem at the end's key path: an unknown kind (with the
        nearest name), a parameter out of its bounds, the factory's verdict.
    """
    kind, problems = end_kind(spec, path)
    if kind is None:
        raise CaseError(problems)
    found = registry.find("boundary", kind)
    if found is None:
        names = registry.names("boundary")
        hint = did_you_mean(kind, names) or "kinds: " + ", ".join(names)
        raise CaseError([Problem(f"{path}.kind", kind, "no such boundary condition kind", hint)])
    record = found.record
    params: dict[str, Any] = {}
    if isinstance(spec, Mapping):
        params, problems = check_params(spec, record.params, path, extra=("kind",))
        if problems:
            raise CaseError(problems)
    problem = abstract_problem(record.factory)
    if problem:
        raise CaseError([Problem(path, MISSING, f"{kind}: {problem}")])
    context = BuildContext(path, spec, str(base_dir), dict(constants or {}), end)
    try:
        condition = record.factory(**params, context=context) if record.context else record.factory(**params)
    except CaseError:
        raise
    except ValueError as exc:  # the factory's verdict on the values
        raise CaseError([Problem(path, MISSING, f"{kind}: {exc}")]) from None
    except Exception as exc:  # the plugin's own code failed, not the case
        raise CaseError([Problem(path, MISSING, f"{kind}: the plugin's factory raised {raised(exc)}")]) from None
    if not isinstance(condition, BoundaryCondition):
        raise CaseError([Problem(path, MISSING, f"{kind}: the factory returned {type(condition).__name__}, "
                                                f"not a BoundaryCondition")])
    return condition, condition.resolved() or {"kind": kind, **params}
