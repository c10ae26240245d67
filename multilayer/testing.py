"""The conformance kit: what a layer plugin must satisfy, for its author's own tests.

A package that ships a layer model runs these checks in its test suite
(pytest is not imported here; the checks raise ``AssertionError``)::

    from multilayer.testing import LayerConformance, assert_layer_conforms

    class TestMyLayer(LayerConformance):        # one test per check
        layer = "my-layer"
        plugins = (my_package.my_layer,)        # not needed once installed (entry point)
        params = {"density": 1.1, "thickness": 0.1, "stiffness": 1e4}  # default: the record's example

    def test_my_layer_conforms(tmp_path):        # or all checks in one test
        assert_layer_conforms("my-layer", plugins=[my_package.my_layer], workdir=tmp_path)

and ``multilayer check-plugin NAME`` runs the same from the command line.
The checks (:data:`CHECKS`):

``schema``
    every parameter has a doc, every float parameter a unit (``"1"`` when
    dimensionless), every default is valid against its own type and bounds,
    and the parameters used are valid against the schema;
``build``
    the factory builds, from those parameters, a ``ThinLayer`` or
    ``ThickLayer`` as the record declares (a band with a thickness);
``matrices``
    on small spaces of order 1 and 2, mass, damping and stiffness are scipy
    sparse matrices of the space's shape, finite, real, symmetric and
    positive semi-definite (smallest eigenvalue ≥ −1e-10 × the largest);
``forces``
    on the same spaces, at :data:`FORCE_STATES` random states (d, v) (on a
    band, displacements of strains ~ :data:`STATE_STRAIN`): the
    tangent K_T(d) against central differences of the force f, the force
    against central differences of the stored energy W (its gradient), the
    damping tangent against differences of the damping force g, the
    dissipation Δt v·g(v) ≥ 0, K_T symmetric, and at rest the tangents equal
    the forms' stiffness and damping; the forms are linear as the layer
    declares (``linear``).  A linear layer's forms pass by construction
    (f = K d); the check is for a nonlinear one's
    (:class:`~multilayer.wall.layer.NonlinearForms`);
``essential-dofs``
    integers within the space;
``coupled-run``
    a short pressure pulse through a coarse channel (:data:`SCENE`, the
    layer on the lumen, or on a ``wave-membrane`` when it is thick; under
    ``monolithic`` when the layer is nonlinear, :data:`NONLINEAR_COUPLER`) runs
    through :func:`multilayer.runner.loop.run_case` and its energy ledger closes:
    ``summary.json`` energy.max_relative_residual ≤ :data:`LEDGER_TOL`
    (a Ctrl-C or a SIGTERM that stops that run is no failed check: once
    the run has stopped, :func:`check_layer` raises
    :class:`~multilayer.plugin.interrupts.UserInterrupt`, a
    ``KeyboardInterrupt``, or :class:`~multilayer.plugin.interrupts.Terminated`).

The parameters are those given, else the record's ``example``, else values
made up from the schema (inside the bounds).
"""

from __future__ import annotations

import copy
import json
import tempfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np
import scipy.sparse as sp

from multilayer.case.casefile import validate_data
from multilayer.geometry.contract import Geometry
from multilayer.geometry.spaces import BandSpace, make_line_space
from multilayer.plugin.interrupts import stopped
from multilayer.plugin.problems import CaseError, check_params, check_value, describe
from multilayer.plugin.records import LayerPlugin, Param
from multilayer.plugin.registry import Registry
from multilayer.runner.loop import run_case
from multilayer.wall.checks import (
    abstract_problem,
    essential_problems,
    linearity_problem,
    matrix_problems,
    raised,
    state_problems,
    type_problem,
)
from multilayer.wall.layer import Layer, LayerMatrices
from multilayer.wall.stack import WallSpace

__all__ = ["CHECKS", "CheckResult", "LayerConformance", "assert_layer_conforms", "check_layer", "example_params",
           "force_problems"]

#: The checks, in the order they run.
CHECKS = ("schema", "build", "matrices", "forces", "essential-dofs", "coupled-run")
#: Largest relative residual of the energy ledger the coupled run may have.
LEDGER_TOL = 1e-9
#: The coupled scene: a pressure pulse through a coarse channel, 10 steps (layers filled in per layer).
SCENE: dict[str, Any] = {
    "title": "conformance: a pressure pulse through a coarse channel",
    "geometry": {"length": 6.0, "radius": 0.5},
    "mesh": {"nz": 12, "nr": 3, "order": 2},
    "time": {"end": 1e-3, "dt": 1e-4},
    "fluid": {"model": "navier-stokes", "density": 1.0, "viscosity": 0.035},
    "coupler": {"model": "kinematic-splitting"},
    "loads": {"inlet": {"model": "cosine-pulse", "amplitude": 1.0e3, "duration": 1e-3}},
}
#: The coupler of the coupled scene for a nonlinear layer (the splitting's default wall impedance needs a linear
#: wall): fluid and wall in one system, iterated by Newton's method.
NONLINEAR_COUPLER = {"model": "monolithic"}
#: Random states (d, v) of the ``forces`` check, per small space.
FORCE_STATES = 3
#: Their size: displacements of 10 % of the small spaces' radius (cm), velocities of 1 cm/s.
STATE_SIZE = (0.05, 1.0)
#: On a band, displacements of at most this times the spacing of its nodes across: strains of about this size (a
#: displacement of 10 % of the radius would turn a thin band's elements inside out, J ≤ 0, where a hyperelastic
#: energy is not defined).
STATE_STRAIN = 0.05
#: The central differences' step, relative to the state: (f(d + h w) − f(d − h w))/2h with |h w| = 1e-4 |d|.
DIFFERENCE_STEP = 1e-4
#: What a tangent or force may differ from the central difference of its force or energy, relative to their size
#: (the differences' own error is ~1e-8 for a force that varies on the scale of the state, round-off ~1e-12).
DIFFERENCE_TOL = 1e-6
#: The thin layer a thick one is put behind in the coupled scene (the kinematic splitting needs one at the fluid).
LUMEN_LAYER = {"model": "wave-membrane", "density": 1.1, "thickness": 0.02, "tension": 2.0e4}
#: The small spaces of the matrix checks: length, radius, cells along z (and radial cells of a band).
SMALL = {"length": 6.0, "radius": 0.5, "nz": 4, "band_cells": 2}


@attrs.frozen
class CheckResult:
    """One check's outcome: its name and what is wrong (nothing when it passed).

    >>> print(CheckResult("schema", ()), CheckResult("build", ("the factory raised KeyError: 'x'",)), sep="\\n")
    ok    schema
    FAIL  build: the factory raised KeyError: 'x'
    """

    name: str
    problems: tuple[str, ...] = attrs.field(converter=tuple)

    @property
    def ok(self) -> bool:
        return not self.problems

    def __str__(self) -> str:
        return f"ok    {self.name}" if self.ok else f"FAIL  {self.name}: " + "; ".join(self.problems)


def example_params(record: LayerPlugin) -> dict[str, Any]:
    """The record's ``example``, or a value inside the bounds for every required parameter.

    >>> from multilayer.plugin.records import LayerPlugin, Param
    >>> record = LayerPlugin("x", dict, (Param("density", gt=0.0), Param("poisson", gt=-1.0, lt=0.5),
    ...                                  Param("cells", type=int, ge=1), Param("viscosity", default=0.0)))
    >>> example_params(record)
    {'density': 1.0, 'poisson': -0.25, 'cells': 2}
    """
    if record.example is not None:
        return dict(record.example)
    return {p.name: _inside(p) for p in record.params if p.required}


def _inside(param: Param) -> Any:
    """A value the parameter accepts: the first choice, or one inside its bounds."""
    if param.choices:
        return param.choices[0]
    if param.type is bool:
        return False
    if param.type is str:
        return "x"
    low = next((b for b in (param.gt, param.ge) if b is not None), None)
    high = next((b for b in (param.lt, param.le) if b is not None), None)
    if low is not None and high is not None:
        value = 0.5 * (low + high)
    elif low is not None:
        value = low + 1.0
    elif high is not None:
        value = high - 1.0
    else:
        value = 1.0
    return int(round(value)) if param.type is int else float(value)


@attrs.define
class _Subject:
    """The layer under test: its record, the parameters, and the object once built."""

    name: str
    registry: Registry
    record: LayerPlugin
    params: dict[str, Any]
    checks: Sequence[str] = CHECKS
    layer: Any = None
    build_problems: list[str] | None = None

    def unbuilt(self) -> list[str]:
        """What a check that needs the layer says when it cannot be built."""
        why = "see build" if "build" in self.checks else "; ".join(self.built()[1])
        return [f"not checked: the layer cannot be built ({why})"]

    def built(self) -> tuple[Any, list[str]]:
        """The layer object (None when it could not be built) and why not."""
        if self.build_problems is None:
            self.build_problems = []
            checked, problems = check_params(self.params, self.record.params, self.name)
            problem = abstract_problem(self.record.factory)
            if problems or problem:
                self.build_problems = [str(p) for p in problems] + ([problem] if problem else [])
                return None, self.build_problems
            try:
                self.layer = self.record.factory(**checked)
            except Exception as exc:  # the plugin's own code
                self.build_problems = [f"the factory raised {raised(exc)}"]
                return None, self.build_problems
            problem = type_problem(self.layer, self.record.thin)
            if problem:
                self.build_problems = [problem]
                self.layer = None
        return self.layer, self.build_problems


def _check_schema(subject: _Subject, workdir: Path) -> list[str]:
    problems = []
    if not subject.record.doc.strip() or "\n" in subject.record.doc.strip():
        problems.append("the record's doc must be one line")
    for p in subject.record.params:
        if not p.doc.strip():
            problems.append(f"parameter {p.name!r} has no doc")
        if p.type is float and not p.unit:
            problems.append(f"float parameter {p.name!r} has no unit (give unit='1' when it is dimensionless)")
        if not p.required and p.default is not None:
            _, ok = check_value(p, p.default)
            if not ok:
                problems.append(f"default of {p.name!r} ({p.default!r}) is not valid against its own schema: "
                                f"expected {describe(p)}")
    _, invalid = check_params(subject.params, subject.record.params, subject.name)
    problems += [f"the parameters used: {p}" for p in invalid]
    return problems


def _small_spaces(layer: Layer, geometry: Geometry) -> list[tuple[int, Any]]:
    """(order, space) for orders 1 and 2: a line of :data:`SMALL` cells, or the band of a small wall."""
    spaces = []
    for order in (1, 2):
        if layer.thin:
            spaces.append((order, make_line_space(SMALL["length"], SMALL["nz"], order, SMALL["radius"], geometry)))
        else:
            wall = WallSpace.build([layer], geometry, SMALL["length"], SMALL["radius"], SMALL["nz"], order,
                                   [SMALL["band_cells"]])
            spaces.append((order, wall.bands[0]))
    return spaces


def _on_small_spaces(subject: _Subject, check: Callable[[Layer, Any], list[str]]) -> list[str]:
    layer, _ = subject.built()
    if layer is None:
        return subject.unbuilt()
    problems, seen = [], set()
    for geometry in _geometries(subject.registry):
        where = "" if geometry.name == "planar" else f" ({geometry.name})"
        for order, space in _small_spaces(layer, geometry):
            try:
                found = check(layer, space)
            except Exception as exc:  # the plugin's own code
                found = [raised(exc)]
            # what the planar space already showed is said once
            problems += [f"order {order}{where}: {p}" for p in found if (order, p) not in seen]
            seen.update((order, p) for p in found)
    return problems


def _geometries(registry: Any) -> list[Geometry]:
    """The geometries the kit's small spaces are built in: planar, then every other one that needs no
    parameter (a tube: a layer's hoop terms are checked too)."""
    out = [registry.get("geometry", "planar").record.factory()]
    for name in sorted(set(registry.names("geometry")) - {"planar"}):
        try:
            geometry = registry.get("geometry", name).record.factory()
        except TypeError:  # it needs parameters: the kit has none to give
            geometry = None
        if isinstance(geometry, Geometry):
            out.append(geometry)
    return out


def _check_matrices(subject: _Subject, workdir: Path) -> list[str]:
    def check(layer: Layer, space: Any) -> list[str]:
        try:
            matrices = layer.forms(space)
        except Exception as exc:  # the plugin's own code
            return [f"forms raised {raised(exc)}"]
        return matrix_problems(matrices, space.ndofs, definite=True)

    return _on_small_spaces(subject, check)


def _check_forces(subject: _Subject, workdir: Path) -> list[str]:
    def check(layer: Layer, space: Any) -> list[str]:
        try:
            forms = layer.forms(space)
        except Exception as exc:  # the plugin's own code
            return [f"forms raised {raised(exc)}"]
        if not isinstance(forms, LayerMatrices):
            return ["not checked: forms did not return LayerMatrices (see matrices)"]
        problem = linearity_problem(layer, forms)
        return [problem] if problem else force_problems(forms, space.ndofs, size=_state_size(space))

    return _on_small_spaces(subject, check)


def _state_size(space: Any) -> float:
    """The size of the random displacements on ``space``: :data:`STATE_SIZE`, and on a band at most
    :data:`STATE_STRAIN` times the spacing of its nodes across."""
    if not isinstance(space, BandSpace):
        return STATE_SIZE[0]
    spacing = space.thickness / SMALL["band_cells"] / space.order
    return min(STATE_SIZE[0], STATE_STRAIN * spacing)


def force_problems(forms: LayerMatrices, n: int, seed: int = 0, size: float = STATE_SIZE[0]) -> list[str]:
    """What is wrong with the forces of ``forms`` on ``n`` DOFs at :data:`FORCE_STATES` random states, their
    displacements of ``size`` (cm).

    The forces of a :class:`~multilayer.wall.layer.LayerMatrices` pass:

    >>> I = sp.identity(3, format="csr")
    >>> force_problems(LayerMatrices(I, I, 2.0 * I), 3)
    []
    """
    rng = np.random.default_rng(seed)
    size_d, size_v = size, STATE_SIZE[1]
    h = DIFFERENCE_STEP
    problems = state_problems(forms, n)
    if problems:
        return problems
    zero = np.zeros(n)
    for name, tangent, matrix in (("tangent", forms.tangent(zero), forms.stiffness),
                                  ("damping_tangent", forms.damping_tangent(zero), forms.damping)):
        gap = _gap(tangent, matrix)
        if gap > DIFFERENCE_TOL:
            part = "stiffness" if name == "tangent" else "damping"
            problems.append(f"{name} at rest differs from the forms' {part} by {gap:.3g} of its size (the matrices "
                            "are the tangents at rest)")
    for _ in range(FORCE_STATES):
        d, w = size_d * rng.standard_normal(n), size_d * rng.standard_normal(n)
        v, u = size_v * rng.standard_normal(n), size_v * rng.standard_normal(n)
        found = state_problems(forms, n, d, v)
        if found:
            return problems + found
        f, K = forms.force(d), sp.csr_matrix(forms.tangent(d))
        difference = (forms.force(d + h * w) - forms.force(d - h * w)) / (2 * h)
        error, scale = np.linalg.norm(K @ w - difference), np.linalg.norm(K @ w) + np.linalg.norm(f)
        if not error <= DIFFERENCE_TOL * scale:
            problems.append(f"the tangent is not the derivative of the force: |K_T(d) w − (f(d + hw) − f(d − hw))/2h| "
                            f"= {error:.3g} against {scale:.3g} (|K_T w| + |f|) at a random state d of size "
                            f"{size_d:g} cm")
        energy = (forms.elastic(d + h * w) - forms.elastic(d - h * w)) / (2 * h)
        error, scale = abs(energy - float(f @ w)), np.linalg.norm(f) * np.linalg.norm(w)
        if not error <= DIFFERENCE_TOL * scale:
            problems.append(f"the force is not the gradient of the energy: |f(d)·w − (W(d + hw) − W(d − hw))/2h| = "
                            f"{error:.3g} against {scale:.3g} (|f| |w|) at a random state d of size {size_d:g} cm")
        asymmetry = _gap(K, K.T)
        if asymmetry > DIFFERENCE_TOL:
            problems.append(f"the tangent is not symmetric at a random state (|K_T − K_Tᵀ| = {asymmetry:.3g} of |K_T|): "
                            "the force is not the gradient of an energy")
        g, C = forms.damping_force(v), sp.csr_matrix(forms.damping_tangent(v))
        difference = (forms.damping_force(v + h * u) - forms.damping_force(v - h * u)) / (2 * h)
        error, scale = np.linalg.norm(C @ u - difference), np.linalg.norm(C @ u) + np.linalg.norm(g)
        if not error <= DIFFERENCE_TOL * scale:
            problems.append(f"the damping tangent is not the derivative of the damping force: |C_T(v) u − "
                            f"(g(v + hu) − g(v − hu))/2h| = {error:.3g} against {scale:.3g}")
        power, taken = float(v @ g), forms.dissipation(v, 1.0)
        negative = power < -1e-12 * np.linalg.norm(v) * np.linalg.norm(g)
        if not abs(taken - power) <= 1e-10 * (abs(power) + abs(taken)) or negative:
            problems.append(f"the dissipation of a step of 1 s at a random velocity is {taken:.6g}, where v·g(v) = "
                            f"{power:.6g} (it must be that, and ≥ 0)")
        if problems:
            return problems
    return problems


def _gap(A: Any, B: Any) -> float:
    """max |A − B| relative to max(|A|, |B|) (0 for two zero matrices)."""
    A, B = sp.csr_matrix(A), sp.csr_matrix(B)
    scale = max(abs(A).max() if A.nnz else 0.0, abs(B).max() if B.nnz else 0.0)
    diff = (A - B)
    gap = abs(diff).max() if diff.nnz else 0.0
    return float(gap / scale) if scale > 0 else float(gap)


def _check_essential(subject: _Subject, workdir: Path) -> list[str]:
    def check(layer: Layer, space: Any) -> list[str]:
        try:
            dofs = layer.essential_dofs(space)
        except Exception as exc:  # the plugin's own code
            return [f"essential_dofs raised {raised(exc)}"]
        return essential_problems(dofs, space.ndofs)

    return _on_small_spaces(subject, check)


def scene(name: str, params: Mapping[str, Any], thin: bool, linear: bool = True) -> dict[str, Any]:
    """The case data of the coupled scene with the layer ``name`` on the lumen (behind a membrane when thick),
    under :data:`NONLINEAR_COUPLER` when the layer is not ``linear``.

    >>> [layer["model"] for layer in scene("linear-elastic", {"thickness": 0.1}, thin=False)["layers"]]
    ['wave-membrane', 'linear-elastic']
    """
    data = copy.deepcopy(SCENE)
    layer = {"model": name, **params}
    data["layers"] = [layer] if thin else [dict(LUMEN_LAYER), {**layer, "cells": 2}]
    if not linear:
        data["coupler"] = dict(NONLINEAR_COUPLER)
    return data


def _check_coupled_run(subject: _Subject, workdir: Path) -> list[str]:

    layer, _ = subject.built()
    if layer is None:
        return subject.unbuilt()
    if not subject.record.thin and subject.registry.find("layer", LUMEN_LAYER["model"]) is None:
        return [f"not checked: the scene puts a thick layer behind {LUMEN_LAYER['model']!r}, which is not installed"]
    try:
        case = validate_data(scene(subject.name, subject.params, subject.record.thin, bool(layer.linear)), workdir,
                             subject.registry)
    except CaseError as exc:
        return [f"the scene is not a valid case: {p}" for p in exc.problems]
    out = workdir / f"check-{subject.name}"
    result = run_case(case, out, subject.registry)
    if result.signal:  # Ctrl-C or SIGTERM, caught by the run: meant for whoever checks, not a failed check
        raise stopped(result.signal)
    summary = json.loads((out / "summary.json").read_text())
    if result.status != "ok":
        return [f"the run failed: {result.reason}"]
    residual = summary["energy"]["max_relative_residual"]
    if not residual <= LEDGER_TOL:
        return [f"the energy ledger does not close: max relative residual {residual:.3g} > {LEDGER_TOL:g} "
                "(are the matrices the layer's energy? see docs/theory.md §7)"]
    return []


_RUNNERS: dict[str, Callable[[_Subject, Path], list[str]]] = {
    "schema": _check_schema,
    "build": lambda subject, workdir: subject.built()[1],
    "matrices": _check_matrices,
    "forces": _check_forces,
    "essential-dofs": _check_essential,
    "coupled-run": _check_coupled_run,
}


def check_layer(name: str, params: Mapping[str, Any] | None = None, registry: Registry | None = None,
                plugins: Iterable[object] = (), checks: Sequence[str] = CHECKS,
                workdir: Path | str | None = None) -> list[CheckResult]:
    """Run the conformance checks on the layer plugin ``name``.

    Parameters
    ----------
    name : str
        The layer's name, as a case file writes it.
    params : mapping, optional
        The parameters to build it with (all of them: they replace the
        record's ``example``, or the values :func:`example_params` makes up).
    registry : Registry, optional
        The plugins; by default the installed ones plus ``plugins``.
    plugins : iterable of modules or objects
        Plugins to register by hand (a module not installed as an entry point).
    checks : sequence of str
        Which of :data:`CHECKS` to run.
    workdir : path, optional
        Where the coupled run writes its results; a temporary folder by default.

    Returns
    -------
    list of CheckResult
        One per check, in order.

    Raises
    ------
    KeyError
        When there is no layer plugin ``name`` (the message has the nearest name).
    ValueError
        For a check name not in :data:`CHECKS`.
    """
    unknown = [c for c in checks if c not in _RUNNERS]
    if unknown:
        raise ValueError(f"no such check {unknown[0]!r}; the checks are {', '.join(CHECKS)}")
    registry = registry or Registry.load(extra=list(plugins))
    record = registry.get("layer", name).record
    subject = _Subject(name, registry, record, dict(params) if params is not None else example_params(record),
                       tuple(checks))
    with tempfile.TemporaryDirectory(prefix="multilayer-check-") as scratch:
        folder = Path(workdir) if workdir is not None else Path(scratch)
        folder.mkdir(parents=True, exist_ok=True)
        return [CheckResult(check, _RUNNERS[check](subject, folder)) for check in checks]


def assert_layer_conforms(name: str, params: Mapping[str, Any] | None = None, registry: Registry | None = None,
                          plugins: Iterable[object] = (), checks: Sequence[str] = CHECKS,
                          workdir: Path | str | None = None) -> None:
    """:func:`check_layer`, raising ``AssertionError`` with one line per failed check.

    In a plugin package's tests (``tests/test_conformance.py`` runs it on the built-in layers)::

        assert_layer_conforms("my-layer", plugins=[my_plugin_module])
        assert_layer_conforms("wave-membrane", checks=("schema", "build", "matrices", "essential-dofs"))
    """
    failed = [r for r in check_layer(name, params, registry, plugins, checks, workdir) if not r.ok]
    if failed:
        raise AssertionError(f"layer {name!r} does not conform:\n" + "\n".join(str(r) for r in failed))


class LayerConformance:
    """Base of a test class: one test per check.  Subclass it as ``Test...`` and set ``layer``.

    Attributes
    ----------
    layer : str
        The layer's name.
    params : dict or None
        Parameters to build it with (default: the record's ``example``).
    plugins : tuple
        Plugin modules to register by hand, for a layer not installed as an entry point.
    """

    layer: str = ""
    params: dict[str, Any] | None = None
    plugins: tuple[object, ...] = ()

    def assert_check(self, check: str, workdir: Path | str | None = None) -> None:
        """Run one check of :data:`CHECKS` on :attr:`layer`."""
        assert self.layer, f"{type(self).__name__}: set the class attribute 'layer' to the layer's name"
        assert_layer_conforms(self.layer, self.params, plugins=self.plugins, checks=(check,), workdir=workdir)

    def test_schema(self) -> None:
        self.assert_check("schema")

    def test_build(self) -> None:
        self.assert_check("build")

    def test_matrices(self) -> None:
        self.assert_check("matrices")

    def test_forces(self) -> None:
        self.assert_check("forces")

    def test_essential_dofs(self) -> None:
        self.assert_check("essential-dofs")

    def test_coupled_run(self, tmp_path: Path) -> None:
        self.assert_check("coupled-run", tmp_path)
