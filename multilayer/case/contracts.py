"""What each kind of plugin's factory must return, checked when validation builds it once.

A factory that passes validation and returns ``None`` (or anything else that
is not the kind's object) would fail the run far from its key; validation
says so at the key path instead.  A fluid must be a
:class:`~multilayer.fluid.contract.Fluid`.  A coupler's class,
:class:`multilayer.coupling.contract.Coupler`, lives in a package above this
one (the import contracts of ``pyproject.toml``), so a coupler is known by
the methods that class declares abstract, :data:`COUPLER_METHODS`
(``tests/test_hostile_inputs.py`` keeps the two in step).  Layers are checked
by :func:`multilayer.wall.checks.type_problem`, geometries and the ends'
conditions where they are built.  A time scheme must be a
:class:`~multilayer.numerics.timescheme.TimeScheme`.
"""

from __future__ import annotations

from typing import Any

from multilayer.fluid.contract import Fluid
from multilayer.numerics.timescheme import TimeScheme

#: the abstract methods of :class:`multilayer.coupling.contract.Coupler`: what makes an object a coupler
COUPLER_METHODS = ("energy", "evolve")


def contract_problem(kind: str, built: Any) -> str | None:
    """Why ``built`` is not what a factory of ``kind`` must return, or None (also for a kind not checked here).

    >>> contract_problem("fluid", None)
    "the plugin's factory returned NoneType, not a Fluid"
    >>> contract_problem("coupler", "kinematic-splitting")
    "the plugin's factory returned str, not a Coupler (it has no energy, evolve)"
    """
    if kind == "fluid" and not isinstance(built, Fluid):
        return f"the plugin's factory returned {type(built).__name__}, not a Fluid"
    if kind == "scheme" and not isinstance(built, TimeScheme):
        return f"the plugin's factory returned {type(built).__name__}, not a TimeScheme"
    if kind == "coupler":
        missing = [m for m in COUPLER_METHODS if not callable(getattr(built, m, None))]
        if missing:
            return f"the plugin's factory returned {type(built).__name__}, not a Coupler (it has no {', '.join(missing)})"
    return None
