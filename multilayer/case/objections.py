"""A coupler's objections to a case: its own reasons, a scheme it cannot step with, adaptive steps it cannot take.

The coupler's reasons are its ``check_case(case)``.  Its scheme is a question of capabilities, never
of names: the coupler says why it cannot step with a scheme (``Coupler.scheme_problems``: its stages,
its levels, a capability flag of the scheme) and whether it takes adaptive steps at all
(``Coupler.adaptive``); the scheme whether it estimates its local error
(``TimeScheme.estimates_error``).  The registry supplies what a message can suggest instead: the
registered schemes the coupler takes, and those of them with an error estimate.  The coupler's class
lives in a package above this one (the import contracts of ``pyproject.toml``), so it is asked by
those attribute names.
"""

from __future__ import annotations

from typing import Any

from multilayer.case.model import Case
from multilayer.case.partial import NotBuilt
from multilayer.numerics.timescheme import TimeScheme, schemes
from multilayer.plugin.problems import MISSING, Problem
from multilayer.plugin.registry import Registry


def coupler_problems(case: Case, registry: Registry) -> list[Problem]:
    """Reasons the case's coupler gives against the case (its optional ``check_case``).

    The coupler factory is called with the case's coupler parameters; a
    ``ValueError`` it raises and every string its ``check_case(case)``
    returns become problems at ``coupler.model``.  (Validation asks the
    coupler itself, in the same pass as every other check.)
    """
    record = registry.get("coupler", case.coupler.model).record
    try:
        coupler = record.factory(**registry.arguments(record, case.coupler.params))
    except ValueError as exc:
        return [Problem(case.coupler.path, MISSING, f"{case.coupler.model}: {exc}")]
    return coupler_objections(coupler, case, registry)


def coupler_objections(coupler: Any, case: Case, registry: Registry | None = None) -> list[Problem]:
    """Every string ``coupler.check_case(case)`` returns, as a problem at ``coupler.model``; with ``registry``
    also why it cannot step with its scheme, or the case's adaptive steps with it (:func:`scheme_objections`).

    ``case`` may have placeholders for parts that could not be built
    (:mod:`multilayer.case.partial`); a coupler that reads one is not asked now.
    """
    check = getattr(coupler, "check_case", None)
    try:
        reasons = list(check(case)) if check is not None else []
    except NotBuilt:
        reasons = []
    problems = [Problem(f"{case.coupler.path}.model", case.coupler.model, str(reason)) for reason in reasons]
    return problems + (scheme_objections(coupler, case, registry) if registry is not None else [])


def scheme_objections(coupler: Any, case: Case, registry: Registry) -> list[Problem]:
    """Why ``coupler`` cannot step ``case`` with its scheme (at ``coupler.scheme``), or cannot take the case's
    adaptive steps with it (at ``coupler.model``, as the coupler's other reasons); empty when it can."""
    scheme = getattr(coupler, "scheme", None)
    refusals = getattr(coupler, "scheme_problems", None)
    if not isinstance(scheme, TimeScheme) or refusals is None:
        return []
    path, model = case.coupler.path, case.coupler.model
    offered = {name: s for name, s in schemes(registry).items() if not refusals(s)}
    reasons = list(refusals(scheme))
    if reasons:
        takes = (f"{model} takes {' or '.join(repr(n) for n in offered)}" if offered
                 else f"{model} takes none of the registered schemes")
        return [Problem(f"{path}.scheme", case.coupler.params.get("scheme", scheme.name), reason, takes)
                for reason in reasons]
    try:
        tolerance = case.time.tolerance
    except NotBuilt:
        return []
    adaptive = getattr(coupler, "adaptive", False) is True
    if tolerance is None or (adaptive and scheme.estimates_error):
        return []
    if scheme.order == 1:  # no second-order pair to estimate with
        because = f"{scheme.name} is first order"
    else:
        because = f"{scheme.name} has none" if adaptive else f"{scheme.name} is not estimated in {model}"
    estimated = [repr(n) for n, s in offered.items() if s.estimates_error]
    if adaptive and estimated:
        instead = f"it takes them with scheme = {' or '.join(estimated)}"
    else:
        couplers = [repr(n) for n in registry.names("coupler")
                    if getattr(registry.get("coupler", n).record.factory, "adaptive", False) is True]
        estimating = [repr(n) for n, s in schemes(registry).items() if s.estimates_error]
        instead = (f"choose a coupler that takes them ({', '.join(couplers) or 'none is installed'}) with a scheme "
                   f"that estimates its error ({', '.join(estimating) or 'none is installed'})")
    return [Problem(f"{path}.model", model,
                    f"time.tolerance = {tolerance:g} asks for adaptive steps, which {model} with scheme "
                    f"{scheme.name!r} does not take (no error estimate: {because}); {instead}, "
                    f"or remove time.tolerance")]
