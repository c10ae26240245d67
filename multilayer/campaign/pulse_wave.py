"""The long-wave speed the whole wall predicts.

* :func:`stack_long_wave_speed` — Moens–Korteweg for the whole stack:
  c² = A/(ρ_f dA/dP) with the static compliance dA/dP of every layer, thin
  and thick (:func:`multilayer.wall.equilibrium.lumen_compliance`);
* the pulse-wave velocity as a clinician measures it, from the feet of a
  pulse in a run's series (``foot``, ``foot_to_foot``, ``loop_speed``), is
  :mod:`multilayer.results.pulse`'s.

Each returns a :class:`Speed`: a positive number, or None and the reason
there is none.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from multilayer.case.model import LayerSpec
from multilayer.plugin.records import MODEL
from multilayer.plugin.registry import Registry
from multilayer.results.pulse import Speed
from multilayer.scene.setup import build_layer
from multilayer.wall.checks import LayerError
from multilayer.wall.equilibrium import lumen_compliance
from multilayer.wall.stack import LUMEN, Stack, WallSpace, fluid_pinned_lines

#: the static deflection under a uniform pressure at L/4 and 3L/4 may differ from the middle's by this fraction
#: and still be the endless wall's: more, and the wall's ends hold it (it has no hoop stiffness of its own)
UNIFORM = 0.05


def radial_power(geometry: Mapping[str, Any], registry: Registry) -> int | None:
    """k of the measure c rᵏ of the resolved ``[geometry]`` (0 planar, 1 a tube); None when its plugin cannot be
    built here."""
    found = registry.find("geometry", geometry.get(MODEL, "planar"))
    if found is None:
        return None
    try:
        shape = found.record.factory(**{k: v for k, v in geometry.items() if k not in (MODEL, "length", "radius")})
    except (TypeError, ValueError):
        return None
    return int(shape.radial_power)


def wall_stack(case: Mapping[str, Any], registry: Registry) -> Stack:
    """The stack of the resolved ``case`` (``summary.json``'s), assembled as a run does on its mesh.

    A fluid on a thick first layer pins the lumen's ends; the d_z a coupler may hold on the lumen is left free
    (far from the ends an endless wall has none to hold).  Raises KeyError, TypeError, ValueError or LayerError
    when the case does not describe a wall.
    """
    geometry, mesh = case["geometry"], case["mesh"]
    found = registry.get("geometry", geometry.get(MODEL, "planar"))
    shape = found.record.factory(**{k: v for k, v in geometry.items() if k not in (MODEL, "length", "radius")})
    specs = []
    for i, spec in enumerate(case["layers"]):
        record = registry.get("layer", spec["model"]).record
        specs.append(LayerSpec(path=f"layers[{i}]", model=spec["model"], thin=record.thin, cells=spec.get("cells"),
                               params={k: v for k, v in spec.items() if k not in ("model", "cells")}))
    layers = [build_layer(registry, spec) for spec in specs]
    space = WallSpace.build(layers, shape, geometry["length"], geometry["radius"], mesh["nz"], mesh["order"],
                            [spec.cells for spec in specs], [spec.model for spec in specs])
    return Stack.assemble(space, (), fluid_pinned_lines(layers, bool(case.get("fluid"))))


def stack_long_wave_speed(case: Mapping[str, Any], registry: Registry) -> Speed:
    """Moens–Korteweg for the whole stack: c² = A/(ρ_f dA/dP) = a/(ρ_f dη/dP), a = R/(1 + k) (theory §11).

    dη/dP is :func:`~multilayer.wall.equilibrium.lumen_compliance` at mid-length, where the ends no longer hold
    the wall; a wall whose deflection at L/4 and 3L/4 differs from the middle's by more than :data:`UNIFORM`
    has no long-wave speed (a wave membrane alone: its ends carry the load, the deflection is a parabola).
    """
    fluid, geometry = case.get("fluid"), case.get("geometry") or {}
    if not fluid:
        return Speed(None, "no fluid")
    if not case.get("layers"):
        return Speed(None, "no wall")
    try:
        stack = wall_stack(case, registry)
        compliance = lumen_compliance(stack)
    except (KeyError, TypeError, ValueError, LayerError) as exc:
        return Speed(None, f"the wall cannot be rebuilt from summary.json: {exc}")
    except RuntimeError:  # splu: an exactly singular stiffness
        return Speed(None, "the wall's stiffness is singular: a motion no layer resists")
    z, L = stack.space.lines[LUMEN].z, geometry["length"]
    at = [compliance[int(np.argmin(np.abs(z - x * L)))] for x in (0.5, 0.25, 0.75)]
    if not at[0] > 0.0:
        return Speed(None, "the lumen does not move out under pressure at mid-length")
    spread = max(abs(a / at[0] - 1.0) for a in at[1:])
    if spread > UNIFORM:
        return Speed(None, f"the wall's deflection under a uniform pressure varies by {spread:.0%} along z: its ends "
                           f"carry part of the load (a layer without hoop stiffness: a membrane, a band in the planar "
                           f"channel)")
    k = stack.space.geometry.radial_power
    return Speed(math.sqrt(geometry["radius"] / (1 + k) / (float(fluid["density"]) * at[0])))
