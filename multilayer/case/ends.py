"""The open ends of the fluid in a case file: each end's condition, looked up in the registry and built.

An end is written as a number (a constant pressure), a string (a pressure
formula in t) or a table ``{model = "<boundary condition>", ...}`` under
``[loads] inlet`` / ``outlet``.  The model is a boundary plugin
(``multilayer plugins``); its parameters are checked against the plugin's
schema, then its factory builds the condition (the factory's own verdict
on the values comes back as problems at the end's key path).  Two ends
that both prescribe their flux are weighed against the wall between them
(:func:`closed_volume_problems`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from multilayer.boundary.contract import BoundaryCondition, BuildContext
from multilayer.case.partial import NotBuilt, Unbuilt
from multilayer.fluid.contract import GIVEN_WALLS
from multilayer.plugin.problems import (
    MISSING,
    CaseError,
    Problem,
    check_params,
    did_you_mean,
    old_model_problems,
)
from multilayer.plugin.records import MODEL
from multilayer.plugin.registry import Registry
from multilayer.wall.checks import abstract_problem, raised

#: the open ends of the fluid, as keys of ``[loads]``
END_KEYS = ("inlet", "outlet")


def end_model(spec: Any, path: str) -> tuple[str | None, list[Problem]]:
    """The boundary condition a case-file value names: a number is ``constant``, a string ``formula``."""
    if isinstance(spec, int | float) and not isinstance(spec, bool):
        if not math.isfinite(spec):
            return None, [Problem(path, spec, "expected a finite pressure (dyn/cm²)")]
        return "constant", []
    if isinstance(spec, str):
        return "formula", []
    if not isinstance(spec, Mapping):
        return None, [Problem(path, spec, "expected a number, a formula in t or a table {model = ...}")]
    if old := old_model_problems(spec, path):
        return None, old
    name = spec.get(MODEL, MISSING)
    if not isinstance(name, str):
        expected = "expected the name of a boundary condition"
        return None, [Problem(f"{path}.{MODEL}", name, ("missing; " if name is MISSING else "") + expected)]
    return name, []


def build_end(spec: Any, path: str, registry: Registry, base_dir: Path | str = ".",
              constants: Mapping[str, float] | None = None, end: float = 1.0
              ) -> tuple[BoundaryCondition, dict[str, Any]]:
    """The condition of one end and its resolved case-file data (defaults filled).

    Raises
    ------
    CaseError
        With every problem at the end's key path: an unknown model (with the
        nearest name), a parameter out of its bounds, the factory's verdict.
    """
    name, problems = end_model(spec, path)
    if name is None:
        raise CaseError(problems)
    found = registry.find("boundary", name)
    if found is None:
        names = registry.names("boundary")
        hint = did_you_mean(name, names) or "available: " + ", ".join(names)
        raise CaseError([Problem(f"{path}.{MODEL}", name, "no such boundary condition", hint)])
    record = found.record
    params: dict[str, Any] = {}
    if isinstance(spec, Mapping):
        params, problems = check_params(spec, record.params, path, extra=(MODEL,))
        if problems:
            raise CaseError(problems)
    problem = abstract_problem(record.factory)
    if problem:
        raise CaseError([Problem(path, MISSING, f"{name}: {problem}")])
    context = BuildContext(path, spec, str(base_dir), dict(constants or {}), end)
    try:
        condition = record.factory(**params, context=context) if record.context else record.factory(**params)
    except CaseError:
        raise
    except ValueError as exc:  # the factory's verdict on the values
        raise CaseError([Problem(path, MISSING, f"{name}: {exc}")]) from None
    except Exception as exc:  # the plugin's own code failed, not the case
        raise CaseError([Problem(path, MISSING, f"{name}: the plugin's factory raised {raised(exc)}")]) from None
    if not isinstance(condition, BoundaryCondition):
        raise CaseError([Problem(path, MISSING, f"{name}: the factory returned {type(condition).__name__}, "
                                                f"not a BoundaryCondition")])
    return condition, condition.resolved() or {MODEL: name, **params}


def closed_volume_problems(case: Any, coupler: Any, resolved: Mapping[str, Mapping[str, Any]]) -> list[Problem]:
    """:func:`given_volume_problems` of ``case``, which may have placeholders (:mod:`multilayer.case.partial`):
    when the coupler (``coupler``; None: it could not be built) says how the fluid sees the wall, and it, both
    ends and the parts it reads to say so were built.  ``resolved`` holds each end's resolved data (its model)."""
    conditions = {end: getattr(case.loads, end) for end in END_KEYS}
    fluid_wall = getattr(coupler, "fluid_wall", None)  # (a coupler is known by its energy and evolve alone)
    if fluid_wall is None or case.fluid is None or any(isinstance(c, Unbuilt) for c in conditions.values()):
        return []
    try:
        wall = fluid_wall(case)
    except NotBuilt:
        return []
    return given_volume_problems(conditions, {end: resolved[end].get(MODEL) for end in END_KEYS}, wall,
                                 case.coupler.model)


def given_volume_problems(conditions: Mapping[str, BoundaryCondition], models: Mapping[str, str], wall: str,
                          coupler: str) -> list[Problem]:
    """Both ends prescribing their flux (a flow rate each) around a fluid that moves no wall.

    ``conditions`` and ``models`` are each end's condition and its model's name, ``wall`` how the fluid sees the
    wall (:meth:`Coupler.fluid_wall`), ``coupler`` the coupler's name.  Under a compliant wall the wall stores
    the difference of the two flow rates and its stiffness sets the pressure; under a rigid or given wall
    (:data:`~multilayer.fluid.contract.GIVEN_WALLS`) the lumen's volume is data, so the two rates are tied to
    it at every step, and no end sets the level of the pressure: the step has no unique solution.

    >>> from types import SimpleNamespace
    >>> flow = SimpleNamespace(constraint=True)  # a flow-rate end
    >>> print(*given_volume_problems({"inlet": flow, "outlet": flow}, {"inlet": "flow-rate", "outlet": "flow-rate"},
    ...                              "rigid", "fluid-only"))  # doctest: +ELLIPSIS
    loads.outlet.model = 'flow-rate': a flow rate at both ends (loads.inlet.model = 'flow-rate' too) of a fluid in \
a rigid wall ('fluid-only'): the volume between them is fixed, so what flows in at one end must flow out at the \
other at every step, and no end sets the level of the pressure; expected a flow rate at one end at most; ...
    """
    if wall not in GIVEN_WALLS or not all(conditions[end].constraint for end in END_KEYS):
        return []
    inlet, outlet = END_KEYS
    volume = {"rigid": f"in a rigid wall ({coupler!r}): the volume between them is fixed, so what flows in at one "
                       f"end must flow out at the other at every step",
              "prescribed": f"whose every step {coupler!r} gives the wall's motion: the volume between them "
                            f"changes only as that motion does, so the two flow rates must add up to its change at "
                            f"every step"}
    return [Problem(f"loads.{outlet}.{MODEL}", models[outlet],
                    f"a flow rate at both ends (loads.{inlet}.{MODEL} = {models[inlet]!r} too) of a fluid {volume[wall]}, "
                    f"and no end sets the level of the pressure; expected a flow rate at one end at most",
                    "give the other end a pressure, a resistance or a windkessel, or couple a compliant wall "
                    "([[layers]] with 'monolithic' or 'kinematic-splitting'), which stores the difference")]
