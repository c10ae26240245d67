"""TOML case files → a validated :class:`multilayer.case.model.Case`.

Every mistake is reported in the user's words — key path, value, what was
expected, the nearest valid name — and all of them at once
(:class:`~multilayer.plugin.problems.CaseError`).  Plugin parameters are checked
against the :class:`~multilayer.plugin.records.Param` schema each plugin registers;
the core sections are checked the same way against the schemas below.
See ``docs/case-files.md`` for the format.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import attrs

from multilayer.case import resources
from multilayer.case.contracts import contract_problem
from multilayer.case.ends import END_KEYS, build_end, closed_volume_problems
from multilayer.case.files import read_case
from multilayer.case.grid import sweep_table
from multilayer.case.initial import closing_problems, initial_data, initial_pressure
from multilayer.case.keys import (
    _blame_overrides,
    apply_overrides,
    key_steps,
    parse_value,
)
from multilayer.case.model import (
    Case,
    Geometry,
    Initial,
    LayerSpec,
    Limits,
    Loads,
    MeshSpec,
    ModelSpec,
    Output,
    Probe,
    TimeSpec,
)
from multilayer.case.objections import coupler_objections, coupler_problems
from multilayer.case.partial import Unbuilt
from multilayer.case.schema import (
    CELLS,
    FLUID_QUANTITIES,
    GEOMETRY,
    LINE_QUANTITIES,
    LOAD_KEYS,
    MESH,
    OUTPUT,
    POINT_QUANTITIES,
    PROBE,
    SECTIONS,
    SOLVER,
    TIME,
    WALL_LOAD_KEYS,
    reserved_column,
    reserved_problem,
)
from multilayer.case.spelling import old_model_keys
from multilayer.case.trial_walls import layer_problems, static_start_problems
from multilayer.functions.domain import Domain, judge
from multilayer.functions.formula import Formula, FormulaError
from multilayer.functions.loads import FormulaPressure, load_from_spec
from multilayer.geometry.contract import Geometry as Shape
from multilayer.numerics.linsolve import SINGLE, Reuse
from multilayer.plugin import units
from multilayer.plugin.problems import (
    MISSING,
    CaseError,
    Problem,
    check_params,
    did_you_mean,
)
from multilayer.plugin.records import MODEL, Param
from multilayer.plugin.registry import Registry
from multilayer.wall.checks import abstract_problem, raised, type_problem

__all__ = ["CaseError", "Problem", "load_case", "read_case", "validate_data", "apply_overrides", "coupler_problems",
           "coupler_objections", "key_steps", "parse_value"]


def load_case(path: Path | str, overrides: Iterable[str] = (), registry: Registry | None = None) -> Case:
    """Read, override and validate a case file.

    Parameters
    ----------
    path : path-like
        The TOML case file.  Table files it names are relative to its folder.
    overrides : iterable of str
        ``dotted.key=value`` strings applied before validation
        (``time.dt=5e-5``, ``layers[0].young=1e6``, ``fluid=none``).
    registry : Registry, optional
        The plugins to validate against; all installed ones by default.

    Raises
    ------
    CaseError
        Listing every problem found, each with its key path.
    """
    path = Path(path)
    data = read_case(path)
    overrides = list(overrides)
    problems = apply_overrides(data, overrides)
    if problems:
        raise CaseError(problems)
    try:
        return validate_data(data, path.parent, registry or Registry.load())
    except CaseError as exc:
        raise CaseError(_blame_overrides(exc.problems, overrides)) from None


def validate_data(data: Mapping[str, Any], base_dir: Path | str = ".", registry: Registry | None = None) -> Case:
    """Validate parsed case data and build the :class:`~multilayer.case.model.Case`.

    Values may carry their units (``"80 mmHg"``, converted to CGS); a plain
    number implausible for its key is noted in ``case.warnings``
    (:mod:`multilayer.plugin.units`).

    Raises
    ------
    CaseError
        Listing every problem found.
    """
    registry = registry or Registry.load()
    with units.collecting() as notes:
        case = _Validator(registry, Path(base_dir)).case(data)
    return attrs.evolve(case, warnings=tuple(notes))


# -- validation -------------------------------------------------------------


class _Validator:
    """One pass over a case: collects every problem, builds the case when there are none."""

    def __init__(self, registry: Registry, base_dir: Path):
        self.registry = registry
        self.base_dir = base_dir
        self.problems: list[Problem] = []
        #: False once a layer is invalid: then H and the line count are unknown
        self.stack_known = True
        #: the coupler built from the case, when it could be: asked for its objections
        self.coupler_object: Any = None
        #: the layer objects built from the case, by key path
        self.built_layers: dict[str, Any] = {}
        #: each open end's condition as resolved case-file data
        self.ends: dict[str, dict[str, Any]] = {}

    def add(self, problems: Iterable[Problem]) -> None:
        self.problems.extend(problems)

    def section(self, data: Mapping[str, Any], name: str, schema: tuple[Param, ...]) -> dict[str, Any]:
        required = [p.name for p in schema if p.required]
        if name not in data and required:
            self.problems.append(Problem(name, MISSING, f"missing; expected a [{name}] table with {', '.join(required)}"))
            return {}
        values, problems = check_params(data.get(name, {}), schema, name)
        self.add(problems)
        return values

    def mark(self) -> int:
        """How many problems there are so far: a part is built when none were added since its mark."""
        return len(self.problems)

    def part(self, where: str, mark: int, build: Callable[[], Any]) -> Any:
        """``build()`` when no problem was added since ``mark``, else a placeholder (:class:`Unbuilt`)."""
        return build() if len(self.problems) == mark else Unbuilt(where)

    def case(self, data: Mapping[str, Any]) -> Case:
        if not isinstance(data, Mapping):
            raise CaseError([Problem("case", data, "expected a table of sections")])
        data, old = old_model_keys(data)  # reported, then read as the model they name: the rest is checked too
        self.add(old)
        self.add(
            Problem(key, value, "unknown section", did_you_mean(key, SECTIONS))
            for key, value in data.items()
            if key not in SECTIONS
        )
        parts: dict[str, Any] = {}
        mark = self.mark()
        title = data.get("title", "")
        if not isinstance(title, str):
            self.problems.append(Problem("title", title, "expected a string"))
        parts["title"] = self.part("title", mark, lambda: title)
        mark = self.mark()
        geometry, shape = self.geometry(data)
        parts["geometry"] = self.part("geometry", mark, lambda: Geometry(**geometry))
        mark = self.mark()
        mesh = self.section(data, "mesh", MESH)
        parts["mesh"] = self.part("mesh", mark, lambda: MeshSpec(**mesh))
        mark = self.mark()
        time = self.section(data, "time", TIME)
        self.add(resources.steps_problems(time))
        parts["time"] = self.part("time", mark, lambda: TimeSpec(**time))
        mark = self.mark()
        fluid = self.fluid(data.get("fluid"))
        parts["fluid"] = self.part("fluid", mark, lambda: fluid)
        mark = self.mark()
        layers, H, parts["layers"] = self.layers(data.get("layers", MISSING), fluid)
        self.add(sized := resources.size_problems(mesh, fluid is not None, layers))
        if self.mark() == mark and shape is not None:
            self.add(layer_problems(layers, self.built_layers, shape, geometry, mesh))
        # every layer built and assembled on the probe wall, and the case fits in memory: the wall can be built
        wall_fits = self.mark() == mark and shape is not None
        coupler = parts["coupler"] = self.coupler(data.get("coupler", MISSING), fluid)
        # stand-ins keep formulas checkable while geometry or time have their own problems
        constants = {"L": geometry.get("length", 1.0), "R": geometry.get("radius", 1.0), "H": H}
        end = time.get("end", 1.0)
        loads = parts["loads"] = self.loads(data.get("loads", {}), constants, end)
        mark = self.mark()
        initial = self.initial(data.get("initial", {}), constants, fluid is not None and bool(layers))
        parts["initial"] = self.part("initial", mark, lambda: initial)
        mark = self.mark()
        output = self.output(data.get("output", {}), constants, fluid, layers)
        parts["output"] = self.part("output", mark, lambda: output)
        mark = self.mark()
        solver = self.section(data, "solver", SOLVER)
        if len(self.problems) == mark and solver["factors"] == "single" and solver["linear"] not in SINGLE:
            self.problems.append(Problem("solver.factors", "single",
                                         f"'double' with linear = {solver['linear']!r} (single-precision factors "
                                         f"need linear = one of {list(SINGLE)})"))
        parts["solver"] = self.part("solver", mark, lambda: solver["linear"])
        parts["limits"] = self.part("solver", mark, lambda: Limits(solver["max_displacement"], solver["energy_margin"],
                                                                    solver["volume_margin"]))
        parts["reuse"] = self.part("solver", mark,
                                   lambda: Reuse(solver["reuse"], solver["max_iterations"], solver["tolerance"],
                                                 solver["factors"], solver["factorization_cost"]))
        parts["threads"] = self.part("solver", mark, lambda: solver["threads"])
        if layers and not sized:  # a wall on a mesh that fits: its initial displacement against the channel
            self.add(closing_problems(*(parts[k] for k in ("geometry", "mesh", "initial", "limits"))))
        case = Case(**parts)
        self.add(self.objections(case))
        self.add(closed_volume_problems(case, self.coupler_object, self.ends))
        problems, found = (static_start_problems(case, self.coupler_object, shape, layers, self.built_layers)
                           if wall_fits else ([], None))  # found: with initial.prestress, the run's reference
        self.add(problems)
        if "sweep" in data:  # checked here; only ``multilayer sweep`` runs it, and it is no part of the case
            self.add(sweep_table(data["sweep"])[1])
        if self.problems:
            raise CaseError(self.problems)

        resolved = {
            "title": title,
            "geometry": {k: v for k, v in geometry.items() if k != "params"} | dict(geometry["params"]),
            "mesh": mesh,
            "time": {k: v for k, v in time.items() if v is not None},  # unset adaptive keys: no trace
            "fluid": None if fluid is None else {"model": fluid.model, **fluid.params},
            "layers": [
                {"model": layer.model, **layer.params, **({} if layer.thin else {"cells": layer.cells})}
                for layer in layers
            ],
            "coupler": {"model": coupler.model, **coupler.params},
            "loads": {
                **{key: self.ends[key] for key in END_KEYS},
                **{key: getattr(loads, key).to_dict() for key in WALL_LOAD_KEYS},
                "wall_motion": None if loads.wall_motion is None else str(loads.wall_motion),
            },
            "initial": initial_data(initial),
            "output": {
                "every": output.every,
                "probes": [
                    {"name": p.name, "quantity": p.quantity, "z": p.z, "r": p.r,
                     "line": p.line if p.quantity in LINE_QUANTITIES else None}
                    for p in output.probes
                ],
            },
            "solver": solver,
        }
        canonical = json.dumps(resolved, sort_keys=True, separators=(",", ":"))
        return attrs.evolve(case, resolved=resolved, digest=hashlib.sha256(canonical.encode()).hexdigest(),
                            base_dir=str(self.base_dir.resolve()), reference=found)

    def objections(self, case: Case) -> list[Problem]:
        """The coupler's reasons against ``case``, when it was built and the parts it reads were too."""
        if self.coupler_object is None:
            return []
        return coupler_objections(self.coupler_object, case, self.registry)

    def model(self, kind: str, spec: Any, path: str, extra: tuple[str, ...] = ()) -> tuple[Any, dict[str, Any], bool] | None:
        """(registered plugin, checked params, params ok) of a ``{model = ..., ...}`` table.

        None when there is no such plugin.
        """
        if isinstance(spec, str):
            spec = {"model": spec}
        if not isinstance(spec, Mapping):
            self.problems.append(Problem(path, spec, f"expected a table with a 'model' key naming a {kind} plugin"))
            return None
        name = spec.get("model", MISSING)
        names = self.registry.names(kind)
        available = "available: " + (", ".join(names) or "none installed")
        if not isinstance(name, str):
            expected = f"expected the name of a {kind} plugin"
            self.problems.append(Problem(f"{path}.model", name, ("missing; " if name is MISSING else "") + expected, available))
            return None
        found = self.registry.find(kind, name)
        if found is None:
            hint = (did_you_mean(name, names) or available) + self.registry.failure_note()
            self.problems.append(Problem(f"{path}.model", name, f"no such {kind} plugin", hint))
            return None
        params, problems = check_params(spec, found.record.params, path, extra=("model", *extra))
        self.add(problems)
        mark = self.mark()
        self.named_plugins(found.record, params, path)
        return found, params, not problems and self.mark() == mark

    def named_plugins(self, record: Any, params: dict[str, Any], path: str) -> None:
        """Each of ``record``'s parameters that names a plugin (``Param.plugin``: a coupler's ``scheme``) looked
        up in the registry, its own parameters checked and the plugin built once; the value of a plugin with
        parameters becomes its table with every default filled in (the resolved case is complete), a plugin
        without any stays its name."""
        for param in record.params:
            value = params.get(param.name)
            if param.plugin is None or value is None:
                continue
            where = f"{path}.{param.name}"
            table = isinstance(value, Mapping)
            name = value[MODEL] if table else value
            found = self.registry.find(param.plugin, name)
            if found is None:
                names = self.registry.names(param.plugin)
                hint = did_you_mean(name, names) + self.registry.failure_note()
                expected = ("expected one of " + ", ".join(repr(n) for n in names) if names
                            else f"no {param.plugin} plugin is installed")
                self.problems.append(Problem(where, value, expected, hint.removeprefix("; ")))
                continue
            checked, problems = check_params(value if table else {}, found.record.params, where, extra=(MODEL,))
            self.add(problems)
            built = None if problems else self.construct(found, checked, where, param.plugin)
            if built is not None and (table or found.record.params):
                params[param.name] = {MODEL: name, **checked}

    def construct(self, found: Any, params: dict[str, Any], path: str, kind: str = "") -> Any:
        """Build the plugin once: only its factory can check constraints across parameters.

        A ``ValueError`` is the factory's verdict on the parameters; any other exception, a class
        with unimplemented abstract methods, or an object that is not of its ``kind`` (:mod:`.contracts`)
        is a mistake in the plugin, reported at ``path`` with the plugin's name; then None.
        """
        problem = abstract_problem(found.record.factory)
        if problem:
            self.problems.append(Problem(path, MISSING, f"{found.name}: {problem}"))
            return None
        try:
            built = found.record.factory(**self.registry.arguments(found.record, params))
            problem = contract_problem(kind, built)
            if problem is None:
                return built
            self.problems.append(Problem(path, MISSING, f"{found.name}: {problem}"))
        except ValueError as exc:
            message = str(exc) if str(exc).startswith(found.name) else f"{found.name}: {exc}"
            self.problems.append(Problem(path, MISSING, message))
        except Exception as exc:  # the plugin's own code failed, not the case
            self.problems.append(Problem(path, MISSING, f"{found.name}: the plugin's factory raised {raised(exc)}"))
        return None

    def fluid(self, spec: Any) -> ModelSpec | None:
        if spec is None or spec == "none" or (isinstance(spec, Mapping) and spec.get("model") == "none"):
            return None
        checked = self.model("fluid", spec, "fluid")
        if checked is None:
            # an invalid fluid is still a fluid: do not add "no fluid" problems on top
            return ModelSpec(path="fluid", model="?")
        found, params, ok = checked
        if ok:
            self.construct(found, params, "fluid", "fluid")
        return ModelSpec(path="fluid", model=found.name, params=params)

    def layers(self, specs: Any, fluid: ModelSpec | None) -> tuple[list[LayerSpec], float, Any]:
        """The valid layers, the thickness H of their bands, and the stack as a part of the case.

        The part is a tuple with a placeholder for each invalid layer, or a
        placeholder for the whole stack when ``layers`` itself is wrong.
        """
        if specs is MISSING:
            specs = []
        if not isinstance(specs, list):
            self.problems.append(Problem("layers", specs, "expected an array of tables [[layers]]"))
            return [], 0.0, Unbuilt("layers")
        if not specs and fluid is None:
            self.problems.append(Problem("layers", MISSING, "missing; a case without a fluid needs at least one [[layers]]"))
            return [], 0.0, Unbuilt("layers")
        layers, H, part = [], 0.0, []
        for i, spec in enumerate(specs):
            path = f"layers[{i}]"
            mark = self.mark()
            found = self.layer(spec, path)
            if found is not None:
                layers.append(found[0])
                H += found[1]
            part.append(self.part(path, mark, lambda: layers[-1]))
        return layers, H, tuple(part)

    def layer(self, spec: Any, path: str) -> tuple[LayerSpec, float] | None:
        """A valid layer and the thickness of its band (0 for a thin layer), or None."""
        spec = {"model": spec} if isinstance(spec, str) else spec
        checked = self.model("layer", spec, path, extra=("cells",))
        if checked is None:
            self.stack_known = False
            return None
        found, params, ok = checked
        thin = found.record.thin
        cells = None
        if thin and "cells" in spec:
            self.problems.append(Problem(f"{path}.cells", spec["cells"], "only a thick layer has radial cells",
                                         f"{found.name!r} is a thin layer"))
        elif not thin:
            values, problems = check_params({k: spec[k] for k in ("cells",) if k in spec}, (CELLS,), path)
            self.add(problems)
            cells = values.get("cells")
        if not ok:
            self.stack_known = False
            return None
        mark = self.mark()
        layer = self.construct(found, params, path)
        problem = type_problem(layer, thin) if self.mark() == mark else None  # (None returned: told already)
        if problem:
            self.problems.append(Problem(path, MISSING, f"{found.name}: {problem}"))
        elif self.mark() == mark:
            self.built_layers[path] = layer
        H = 0.0 if thin else float(getattr(layer, "thickness", params.get("thickness", 0.0)) or 0.0)
        linear = bool(getattr(layer, "linear", True))
        return LayerSpec(path=path, model=found.name, params=params, thin=thin, cells=cells, linear=linear), H

    def geometry(self, data: Mapping[str, Any]) -> tuple[dict[str, Any], Shape | None]:
        """The ``[geometry]`` values (its plugin's parameters under ``params``) and the geometry, built."""
        table = data.get("geometry", MISSING)
        name = table.get(MODEL, "planar") if isinstance(table, Mapping) else "planar"
        found = self.registry.find("geometry", name) if isinstance(name, str) else None
        if found is None:
            names = self.registry.names("geometry")
            hint = did_you_mean(name, names) if isinstance(name, str) else ""
            self.problems.append(Problem(f"geometry.{MODEL}", name, "no such geometry plugin",
                                         hint or "available: " + (", ".join(names) or "none installed")))
            return self.section(data, "geometry", GEOMETRY[:2]), None
        own = found.record.params
        values = self.section(data, "geometry", GEOMETRY + own)
        params = {p.name: values.pop(p.name) for p in own if p.name in values}
        mark = self.mark()
        shape = self.construct(found, params, "geometry")
        if self.mark() != mark or not isinstance(shape, Shape):
            if self.mark() == mark:
                self.problems.append(Problem(f"geometry.{MODEL}", name, "the plugin's factory returned "
                                             f"{type(shape).__name__}, not a Geometry"))
            shape = None
        return {**values, "params": params}, shape

    def coupler(self, spec: Any, fluid: ModelSpec | None) -> ModelSpec:
        default = "structure-only" if fluid is None else "kinematic-splitting"
        if spec is MISSING:
            spec = {"model": default}
        elif isinstance(spec, Mapping) and "model" not in spec:
            spec = {"model": default, **spec}
        checked = self.model("coupler", spec, "coupler")
        if checked is None:
            return ModelSpec(path="coupler", model="?")
        found, params, ok = checked
        if ok:
            self.coupler_object = self.construct(found, params, "coupler", "coupler")
        return ModelSpec(path="coupler", model=found.name, params=params)

    def formula(self, expr: Any, path: str, constants: Mapping[str, float], domain: Domain) -> Formula:
        """The formula at ``path``, checked, then judged on ``domain`` (the ranges of its variables)."""
        variables = tuple(domain.ranges)
        try:
            formula = Formula.parse(expr, constants, variables)
        except FormulaError as exc:
            self.problems.append(Problem(path, expr, f"invalid formula in {', '.join(variables)}: {exc}"))
            return Formula.zero()
        self.judge(formula, path, domain)
        return formula

    def judge(self, formula: Formula, path: str, domain: Domain) -> None:
        """A problem at ``path`` when ``formula`` is not a finite real number somewhere on ``domain``."""
        problem = judge(formula, path, domain)
        if problem is not None:
            self.problems.append(problem)

    def table(self, data: Any, path: str, keys: Iterable[str]) -> Mapping[str, Any]:
        """A table whose keys must be among ``keys``; {} (with a problem) if it is not a table."""
        if not isinstance(data, Mapping):
            self.problems.append(Problem(path, data, "expected a table"))
            return {}
        keys = list(keys)
        self.add(
            Problem(f"{path}.{k}", v, "unknown key", did_you_mean(k, keys)) for k, v in data.items() if k not in keys
        )
        return data

    def loads(self, data: Any, constants: Mapping[str, float], end: float) -> Loads:
        data = self.table(data, "loads", (*LOAD_KEYS, "wall_motion"))
        pressures = {}
        for key in END_KEYS:
            mark = self.mark()
            try:
                condition, self.ends[key] = build_end(data.get(key, 0.0), f"loads.{key}", self.registry,
                                                      self.base_dir, constants, end)
            except CaseError as exc:
                self.add(exc.problems)
                condition = None
            pressures[key] = self.part(f"loads.{key}", mark, lambda: condition)
        for key in WALL_LOAD_KEYS:
            spec, mark = data.get(key, 0.0), self.mark()
            try:
                load = load_from_spec(spec, f"loads.{key}", self.base_dir, constants)
            except CaseError as exc:
                self.add(exc.problems)
                load = None
            if isinstance(load, FormulaPressure):
                where = f"loads.{key}" if isinstance(spec, str) else f"loads.{key}.expr"
                self.judge(load.formula, where, Domain({"t": (0.0, end)}))
            pressures[key] = self.part(f"loads.{key}", mark, lambda: load)
        motion, mark = data.get("wall_motion"), self.mark()
        wall_motion = None if motion is None else self.formula(
            motion, "loads.wall_motion", constants, Domain({"t": (0.0, end), "z": (0.0, constants["L"])}))
        return Loads(**pressures, wall_motion=self.part("loads.wall_motion", mark, lambda: wall_motion))

    def initial(self, data: Any, constants: Mapping[str, float], coupled: bool) -> Initial:
        pressure, prestress, problems = initial_pressure(data, coupled)
        self.add(problems)
        data = data if isinstance(data, Mapping) else {}
        fields = {}
        for name in ("displacement", "velocity"):
            part = self.table(data.get(name, {}), f"initial.{name}", ("r", "z"))
            # evaluated on the wall: z along the channel, r across every band (the lumen line alone without one)
            wall = Domain({"z": (0.0, constants["L"]), "r": (constants["R"], constants["R"] + constants["H"])})
            for component in ("r", "z"):
                fields[f"{name}_{component}"] = self.formula(
                    part.get(component, "0"), f"initial.{name}.{component}", constants, wall
                )
        return Initial(**fields, pressure=pressure, prestress=prestress)

    def output(self, data: Any, constants: Mapping[str, float], fluid: ModelSpec | None, layers: list[LayerSpec]) -> Output:
        values, problems = check_params(data, OUTPUT, "output", extra=("probes",))
        self.add(problems)
        specs = data.get("probes", []) if isinstance(data, Mapping) else []
        if not isinstance(specs, list):
            self.problems.append(Problem("output.probes", specs, "expected an array of tables"))
            specs = []
        lines = sum(not layer.thin for layer in layers)
        probes, names = [], set()
        for i, spec in enumerate(specs):
            probe = self.probe(spec, f"output.probes[{i}]", constants, fluid, lines, bool(layers))
            if probe is None:
                continue
            if probe.name in names:
                self.problems.append(Problem(f"output.probes[{i}].name", probe.name, "a probe of that name exists already"))
            elif reserved_column(probe.name):
                self.problems.append(reserved_problem(f"output.probes[{i}].name", probe.name, probe.place))
            names.add(probe.name)
            probes.append(probe)
        return Output(every=values.get("every", 0), probes=tuple(probes))

    def probe(self, spec: Any, path: str, constants: Mapping[str, float], fluid: ModelSpec | None, lines: int,
              has_wall: bool) -> Probe | None:
        values, problems = check_params(spec, PROBE, path)
        if problems:
            self.add(problems)
            return None
        q, z, r, line = values["quantity"], values["z"], values["r"], values["line"]
        L, R, H = constants["L"], constants["R"], constants["H"]
        found = []
        if fluid is None and q in FLUID_QUANTITIES:
            found.append(Problem(f"{path}.quantity", q, "a fluid quantity, but the case has no fluid"))
        if self.stack_known and q not in FLUID_QUANTITIES:
            if not has_wall:
                found.append(Problem(f"{path}.quantity", q, "a wall quantity, but the case has no [[layers]]"))
            elif q in ("d_z", "d_r") and lines == 0:
                found.append(Problem(f"{path}.quantity", q, "a displacement inside a thick band, but the stack has "
                                     "no thick layer", "measure a thin layer with quantity = \"eta\""))
        if not 0.0 <= z <= L:
            found.append(Problem(f"{path}.z", z, f"expected a position in [0, L = {L:g}] (cm)"))
        if q in POINT_QUANTITIES:
            lo, hi = (0.0, R) if q in FLUID_QUANTITIES else (R, R + H)
            if r is None:
                found.append(Problem(f"{path}.r", MISSING, f"missing; {q} is measured at a point (z, r), r in [{lo:g}, {hi:g}] (cm)"))
            elif self.stack_known and not lo - 1e-12 * hi <= r <= hi * (1 + 1e-12):
                found.append(Problem(f"{path}.r", r, f"expected a radius in [{lo:g}, {hi:g}] (cm) for {q}"))
        elif r is not None:
            found.append(Problem(f"{path}.r", r, f"{q} takes no r", "r applies to " + ", ".join(POINT_QUANTITIES)))
        if q in LINE_QUANTITIES:
            line = 0 if line is None else line
            if self.stack_known and line > lines:
                found.append(Problem(f"{path}.line", line, f"expected an interface line 0..{lines} (0 = lumen)"))
        elif line is not None:
            found.append(Problem(f"{path}.line", line, f"{q} takes no line", "line applies to eta and v"))
        self.add(found)
        if found:
            return None
        probe = Probe(name="", quantity=q, z=z, r=r, line=line or 0)
        return attrs.evolve(probe, name=values["name"] or probe.place)
