"""The initial wall against the geometry: a lumen displacement that closes the channel is refused at validation;
a wall given both as a displacement and as the static equilibrium under ``initial.pressure`` too.

``initial.displacement.r`` is judged on its domain like every formula (finite
and real); here it is also weighed against the channel it displaces: the run
stops at once on a lumen with R + η ≤ 0 or |η| beyond ``[solver]
max_displacement`` × R, and that check names no key, so validation does.
The static start under ``initial.pressure`` is weighed the same way
(:mod:`multilayer.case.trial_walls`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from multilayer.case.model import Geometry, Initial, Limits, MeshSpec
from multilayer.case.schema import INITIAL
from multilayer.plugin.problems import Problem, check_params

WHERE = "initial.displacement.r"
#: At most this many points along z are evaluated (evenly spaced when the lumen has more nodes).
MAX_POINTS = 1_000_000


def closing_problems(geometry: Any, mesh: Any, initial: Any, limits: Any) -> list[Problem]:
    """The initial lumen displacement η⁰ closing the channel (R + η⁰ ≤ 0) or beyond ``[solver] max_displacement``.

    ``initial.displacement.r`` is evaluated at r = R on the lumen's nodes along z (order × nz cells; the
    ends are held at zero by the layers, so the interior ones; at most
    :data:`MAX_POINTS` of them), where the
    run's first check of the state would find it.  Each part may be a
    placeholder (:mod:`multilayer.case.partial`): without geometry, mesh
    and initial there is nothing to weigh, without limits only the gap.

    >>> from multilayer.functions.formula import Formula
    >>> zero = Formula.parse("0", {}, ("z", "r"))
    >>> eta = Formula.parse("-0.6*sin(pi*z/L)", {"L": 6.0}, ("z", "r"))
    >>> g, m = Geometry(6.0, 0.5), MeshSpec(6, 2, 2)
    >>> print(*closing_problems(g, m, Initial(zero, eta, zero, zero), Limits(2.0)))
    initial.displacement.r = '-0.6*sin(pi*z/L)': gives η = -0.6 cm at z = 3 cm on the lumen (r = R = 0.5 cm): \
R + η ≤ 0 closes the channel; the initial radial displacement must keep R + η > 0 on the lumen
    """
    if not (isinstance(geometry, Geometry) and isinstance(mesh, MeshSpec) and isinstance(initial, Initial)):
        return []
    L, R, expr = geometry.length, geometry.radius, str(initial.displacement_r)
    nodes = mesh.order * mesh.nz
    if nodes < 2:
        return []
    z = np.linspace(0.0, L, min(nodes, MAX_POINTS) + 1)[1:-1]
    with np.errstate(all="ignore"):
        try:
            eta = np.broadcast_to(np.asarray(initial.displacement_r(z=z, r=R), dtype=float), z.shape)
        except (ValueError, TypeError, ArithmeticError):
            return []  # (judged on its domain already)
    if not np.all(np.isfinite(eta)):
        return []  # (judged on its domain already)
    i = int(np.argmin(eta))
    if R + eta[i] <= 0.0:
        return [Problem(WHERE, expr, f"gives η = {eta[i]:.6g} cm at z = {z[i]:.6g} cm on the lumen (r = R = {R:g} cm): "
                                     f"R + η ≤ 0 closes the channel",
                        "the initial radial displacement must keep R + η > 0 on the lumen")]
    if isinstance(limits, Limits):
        limit = limits.max_displacement * R
        i = int(np.argmax(np.abs(eta)))
        if abs(eta[i]) > limit:
            return [Problem(WHERE, expr, f"gives |η| = {abs(eta[i]):.6g} cm at z = {z[i]:.6g} cm on the lumen, more "
                                         f"than [solver] max_displacement = {limits.max_displacement:g} R = "
                                         f"{limit:.6g} cm: the run would stop at once",
                            "a smaller displacement, or a larger solver.max_displacement")]
    return []


def equilibrium_problems(pressure: float | None, initial: Any) -> list[Problem]:
    """``initial.pressure`` (the wall's static equilibrium, :mod:`multilayer.wall.equilibrium`) given together
    with the ``initial`` table's ``displacement`` or ``velocity``: the wall would be given twice.

    >>> print(*equilibrium_problems(2000.0, {"displacement": {"r": "0.01"}}))
    initial.pressure = 2000.0: sets the initial wall (its static equilibrium), and initial.displacement too; \
leave initial.displacement out
    >>> equilibrium_problems(None, {"displacement": {"r": "0.01"}}), equilibrium_problems(2000.0, {})
    ([], [])
    >>> equilibrium_problems(2000.0, {"displacement": {"r": "0", "z": "0"}})  # a resolved case's defaults
    []
    """
    given = " and ".join(f"initial.{name}" for name in ("displacement", "velocity") if _given(initial.get(name)))
    if pressure is None or not given:
        return []
    return [Problem("initial.pressure", pressure, f"sets the initial wall (its static equilibrium), and {given} too",
                    f"leave {given} out")]


def _given(table: Any) -> bool:
    """Whether an ``initial.displacement`` or ``velocity`` table is given: present, and not the zero a resolved
    case writes for it (``{r = "0", z = "0"}``, read back on resume).

    >>> _given(None), _given({"r": "0", "z": "0"}), _given({"r": "0.01"})
    (False, False, True)
    """
    if table is None:
        return False
    return not (isinstance(table, dict) and all(str(v).strip() in ("0", "0.0") for v in table.values()))


def initial_pressure(data: Any, coupled: bool) -> tuple[float | None, bool, list[Problem]]:
    """The ``[initial]`` table's ``pressure`` (None: unset), ``prestress`` and their problems: the table's keys
    (``displacement`` and ``velocity`` are read by the caller), a case without both a fluid and a wall
    (``coupled`` False: there is no fluid to rest at it, or no wall to hold it), a prestress without a pressure
    (the geometry imaged under what?), and :func:`equilibrium_problems`.

    >>> print(*initial_pressure({"pressure": 2000.0}, coupled=False)[2])
    initial.pressure = 2000.0: a fluid at rest at a pressure against a wall, but the case has not both; \
leave initial.pressure out
    >>> print(*initial_pressure({"prestress": True}, coupled=True)[2])
    initial.prestress = true: the geometry as imaged under initial.pressure, but initial.pressure is unset; \
set initial.pressure (the pressure the wall was imaged at), or leave initial.prestress out
    """
    values, problems = check_params(data, INITIAL, "initial", extra=("displacement", "velocity"))
    pressure, prestress = values.get("pressure"), bool(values.get("prestress", False))
    if pressure is not None and not coupled:
        problems.append(Problem("initial.pressure", pressure, "a fluid at rest at a pressure against a wall, but "
                                "the case has not both", "leave initial.pressure out"))
    if prestress and pressure is None:
        problems.append(Problem("initial.prestress", True, "the geometry as imaged under initial.pressure, but "
                                "initial.pressure is unset", "set initial.pressure (the pressure the wall was "
                                "imaged at), or leave initial.prestress out"))
    return pressure, prestress, problems + (equilibrium_problems(pressure, data) if isinstance(data, dict) else [])


def initial_data(initial: Initial) -> dict[str, Any]:
    """``initial`` as the resolved case writes it; ``pressure`` only when set, ``prestress`` only when true (a case
    without them keeps its hash)."""
    return {"displacement": {"r": str(initial.displacement_r), "z": str(initial.displacement_z)},
            "velocity": {"r": str(initial.velocity_r), "z": str(initial.velocity_z)},
            **({} if initial.pressure is None else {"pressure": initial.pressure}),
            **({"prestress": True} if initial.prestress else {})}
