"""The walls validation builds to try a case's layers before a run: a small one, and the case's own.

Each layer assembles on a small wall (:mod:`multilayer.wall.probe`), so a
plugin's mistake is reported at the layer's key path.  With ``[initial]
pressure`` the case's own wall is built as the run builds it (its mesh, its
coupler's radial lines, a fluid's pinned lumen ends) and the run's static
start is solved on it (:func:`multilayer.wall.equilibrium.static_deflection`):
a start the wall cannot hold is refused at ``initial.pressure`` with the
deflection it implies, rather than failing, or running far outside the
linear wall's range, once the run has started.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from multilayer.case.model import (
    FoundReference,
    Initial,
    LayerSpec,
    Limits,
    reference_inputs,
)
from multilayer.case.partial import NotBuilt
from multilayer.geometry.contract import Geometry as Shape
from multilayer.numerics.linsolve import SolverStats
from multilayer.numerics.newton import NewtonError
from multilayer.plugin.problems import MISSING, Problem
from multilayer.wall import probe
from multilayer.wall.checks import LayerError
from multilayer.wall.equilibrium import Unsettled, static_deflection
from multilayer.wall.prestress import PrestressError, prestress
from multilayer.wall.stack import LUMEN, Stack, WallSpace, fluid_pinned_lines

#: The largest static deflection |η| of the lumen under ``initial.pressure``, as a fraction of R, that validation
#: admits.  The layers are linear, small-strain models: in a tube η/R is the hoop strain, whose quadratic term
#: (η/R)²/2 they leave out (an eighth of it at R/4), while the pressure on the moved lumen, which the static
#: start keeps, makes a fifth of the deflection there (η = η₁(1 + η/R), η₁ the linear one); beyond, the start
#: is outside the model (and far beyond, a unit slipped: moduli in kPa or Pa, not dyn/cm²).  A wall whose layers
#: are all nonlinear (finite-strain: a hyperelastic membrane) is not bound by it.
SMALL_DEFLECTION = 0.25
#: what a deflection far beyond the bound most often means
UNITS = ("check that the layers' moduli and initial.pressure are in dyn/cm² (1 kPa = 1e4 dyn/cm², "
         "1 mmHg = 1333.2 dyn/cm²)")
#: a stress-free reference found: its displacement D from the mesh (wall numbering) and its static solves' counters
Found = tuple[np.ndarray, SolverStats]


def layer_problems(layers: Sequence[LayerSpec], built: Mapping[str, Any], shape: Shape,
                   geometry: Mapping[str, float], mesh: Mapping[str, Any]) -> list[Problem]:
    """What each layer returns wrong on a small wall (:mod:`multilayer.wall.probe`), at its key path.

    ``built`` holds the layer objects by key path; only when every layer was built as a layer of its kind and
    nothing else is wrong with the stack: a wall cannot be placed otherwise.
    """
    if not layers or len(built) != len(layers):
        return []
    found = probe.probe([built[layer.path] for layer in layers], [layer.model for layer in layers], shape,
                        geometry.get("length", 1.0), geometry.get("radius", 1.0), mesh.get("order", 2))
    return [Problem(layers[index].path, MISSING, f"{layers[index].model}: " + "; ".join(problems))
            for index, problems in found.items()]


def static_start_problems(case: Any, coupler: Any, shape: Shape, layers: Sequence[LayerSpec],
                          built: Mapping[str, Any]) -> tuple[list[Problem], FoundReference | None]:
    """With ``initial.pressure``, the static start solved on the case's wall as the run solves it and weighed
    against the channel (:func:`deflection_problems`); with ``initial.prestress``, the stress-free reference
    found (:func:`prestress_problems`), and returned for the run to set up on (None: not found, or no prestress).

    ``case`` may have placeholders (:mod:`multilayer.case.partial`); ``coupler`` is the coupler object (None:
    it could not be built), ``built`` the layer objects by key path.  Nothing is solved unless the coupler says
    which lines it holds radially and every part the start reads was built; a layer that fails on the full wall
    is left to the run, which names it.
    """
    radial_lines = getattr(coupler, "radial_lines", None)  # (a coupler is known by its energy and evolve alone)
    if not isinstance(case.initial, Initial) or case.initial.pressure is None or radial_lines is None:
        return [], None
    try:
        g, m, external = case.geometry, case.mesh, case.loads.external.value(0.0)
        objects = [built[layer.path] for layer in layers]
        space = WallSpace.build(objects, shape, g.length, g.radius, m.nz, m.order, [layer.cells for layer in layers],
                                [layer.model for layer in layers])
        stack = Stack.assemble(space, radial_lines(case), fluid_pinned_lines(objects, case.fluid is not None))
    except (NotBuilt, LayerError):
        return [], None
    if case.initial.prestress:
        problems, found = prestress_problems(case.initial.pressure, external, stack)
        try:  # with what it was found from (a part not built: the case is refused for its own problems)
            return problems, None if found is None else FoundReference(*found, reference_inputs(case))
        except NotBuilt:
            return problems, None
    return deflection_problems(case.initial.pressure, external, stack, case.limits), None


def prestress_problems(pressure: float, external: float, stack: Stack) -> tuple[list[Problem], Found | None]:
    """With ``initial.prestress``, the stress-free reference the run sets up on (:func:`~multilayer.wall.prestress.prestress`),
    found here once (returned with the counters of its static solves, None when refused): refused at
    ``initial.prestress`` when the wall has no finite-strain layer, when the fixed point does not converge (its
    iterations and the last out-of-balance force said), or when a layer fails on it.  The wall sits on the mesh,
    so there is no deflection to weigh."""
    stats = SolverStats()
    try:
        found = prestress(stack, pressure, external, stats)
    except PrestressError as exc:
        return [Problem("initial.prestress", True, f"the wall imaged at initial.pressure = {pressure:g} dyn/cm²: "
                        f"{exc}", "a smaller initial.pressure (the wall's imaged geometry may be beyond what its "
                        "layers hold), or leave initial.prestress out")], None
    except LayerError as exc:
        return [Problem("initial.prestress", True, f"a layer fails on the stress-free reference: {exc}",
                        "a smaller initial.pressure, or leave initial.prestress out")], None
    return [], (found.reference, attrs.evolve(stats, backends={}))  # its counts, not the solvers' objects


def deflection_problems(pressure: float, external: float, stack: Stack, limits: Any) -> list[Problem]:
    """The wall's static start under ``initial.pressure`` (:func:`~multilayer.wall.equilibrium.static_deflection`,
    the run's own solve) weighed against the channel.

    Refused, at ``initial.pressure``: a lumen moved by more than :data:`SMALL_DEFLECTION` × R (or
    ``[solver] max_displacement`` × R when that is less: the run would stop at once; a wall whose layers are all
    nonlinear, finite-strain models, has no small-strain bound: max_displacement alone), a pressure on the moved
    lumen that outgrows the wall (no equilibrium settles: the linear deflection is reported), and a wall whose
    stiffness is singular.  ``external`` is the outer pressure at t = 0; ``limits`` may be a placeholder
    (:mod:`multilayer.case.partial`): then the small-strain bound alone.
    """
    R = stack.space.radius
    bound, why, hint = SMALL_DEFLECTION, "the linear wall's small strain", "a smaller initial.pressure or a stiffer wall"
    # a wall of finite-strain layers only (every layer nonlinear: a hyperelastic membrane) has no small-strain bound;
    # the run's own limit stays
    finite_strain = not any(m.linear for m in stack.matrices)
    if finite_strain:
        bound, why = math.inf, ""
    if isinstance(limits, Limits) and limits.max_displacement < bound:
        bound, why = limits.max_displacement, "[solver] max_displacement: the run would stop at once"
        hint = "a smaller initial.pressure, a stiffer wall or a larger solver.max_displacement"
    loads = "under it" + (f" and loads.external = {external:g} at t = 0" if external else "")
    expected = f"; expected |η| ≤ {bound:g} R = {bound * R:.6g} cm ({why})" if math.isfinite(bound) else ""
    try:
        d, settles = static_deflection(stack, pressure, external), True
    except Unsettled as exc:
        d, settles = exc.linear, False
    except NewtonError as exc:  # a nonlinear layer's equilibrium that Newton does not reach
        return [Problem("initial.pressure", pressure, f"the wall's static equilibrium {loads} is not found: {exc}",
                        "a smaller initial.pressure, or check the nonlinear layer's force and tangent "
                        "(multilayer check-plugin)")]
    except RuntimeError as exc:  # splu: the stiffness is exactly singular
        return [Problem("initial.pressure", pressure, f"the wall has no static equilibrium {loads}: its stiffness is "
                        f"singular ({exc}: a motion of the wall that no layer resists)",
                        "give the layers stiffness, or leave initial.pressure out")]
    eta, z = stack.space.restrictions[LUMEN] @ d, stack.space.lines[LUMEN].z
    i = int(np.argmax(np.abs(eta)))
    moved = f"η = {eta[i]:.6g} cm at z = {z[i]:.6g} cm, {abs(eta[i]) / R:.3g} R (R = {R:g} cm)"
    if not settles or abs(eta[i]) >= R:  # far beyond the bound: more likely a unit than a pressure
        hint = f"{hint}; {UNITS}"
    if not settles:
        alone = (f"{loads}, on the lumen at rest, the wall moves it" if finite_strain
                 else f"{loads} the linear wall alone moves the lumen")
        beyond = ("; a finite-strain wall holds no more than its largest pressure, hc/(Rλz0) for a thin neo-Hookean "
                  "tube, docs/theory.md §1" if finite_strain else "")
        return [Problem("initial.pressure", pressure, f"the wall cannot hold it: {alone} by {moved}, and the "
                        f"pressure on the moved lumen outgrows its stiffness (no static equilibrium settles{beyond})"
                        f"{expected}", hint)]
    if abs(eta[i]) <= bound * R:
        return []
    closes = " (R + η ≤ 0: the lumen closes)" if R + eta[i] <= 0.0 else ""
    return [Problem("initial.pressure", pressure, f"the wall's static equilibrium {loads} moves the lumen by "
                    f"{moved}{closes}{expected}", hint)]
