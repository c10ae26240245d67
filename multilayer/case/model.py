"""The case model: a validated scene, as frozen values.

A case file (TOML) is parsed and validated by :mod:`multilayer.case.casefile`
into a :class:`Case`; nothing downstream reads raw TOML.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from multilayer.boundary.contract import BoundaryCondition
from multilayer.functions.formula import Formula
from multilayer.functions.loads import PressureLoad
from multilayer.numerics.linsolve import Reuse, SolverStats


@attrs.frozen
class Geometry:
    length: float  #: L (cm), channel length
    radius: float  #: R (cm), reference radius of the lumen
    model: str = "planar"  #: the geometry plugin (``[geometry] model``): what the meridian plane stands for
    params: Mapping[str, Any] = attrs.field(factory=dict, eq=False)  #: its own parameters


@attrs.frozen
class MeshSpec:
    nz: int  #: cells along z, shared by every field
    nr: int  #: fluid cells across (0, R)
    order: int  #: 1 (P1 / MINI) or 2 (P2 / Taylor–Hood)
    grading: float = 1.0  #: fluid grading toward the wall (1 = uniform)


#: the smallest adaptive step when time.dt_min is not set, as a fraction of time.dt
DT_MIN_FRACTION = 1e-6


@attrs.frozen
class TimeSpec:
    end: float  #: T (s)
    dt: float  #: Δt (s); with ``tolerance`` the first step
    tolerance: float | None = None  #: adaptive steps: the relative error allowed (None: fixed steps of dt)
    dt_min: float | None = None  #: adaptive steps: the smallest step (s; None: dt × :data:`DT_MIN_FRACTION`)
    dt_max: float | None = None  #: adaptive steps: the largest step (s; None: no bound)
    output_interval: float | None = None  #: adaptive steps land on its multiples (s)
    memory: float | None = None  #: adaptive steps: the memory time W (s; None: the loads' shortest period, or end)
    control: str | None = None  #: adaptive steps: "per-step" (None) or "per-unit-step" (multilayer.coupling.clock)
    size: str | None = None  #: adaptive steps: a field's size "so-far" or over the last "memory" time (None: :meth:`sizing`)

    @property
    def adaptive(self) -> bool:
        """True when the steps are chosen by error (``tolerance`` set)."""
        return self.tolerance is not None

    @property
    def sharing(self) -> str:
        """How an adaptive run shares its tolerance among its steps: ``control``, by default "per-step"."""
        return self.control or "per-step"

    def sizing(self, loads: Sequence[PressureLoad]) -> str:
        """What an adaptive run measures a field's error against: ``size``, by default "memory" when a load is
        periodic (a cardiac cycle: its first cycle measured as the later ones) and "so-far" otherwise.

        >>> from multilayer.functions.loads import ConstantPressure, SinePressure
        >>> time = TimeSpec(end=1.0, dt=1e-3, tolerance=1e-3)
        >>> time.sizing([ConstantPressure(1.0)]), time.sizing([SinePressure(1.0, 4.0)])
        ('so-far', 'memory')
        >>> attrs.evolve(time, size="so-far").sizing([SinePressure(1.0, 4.0)])
        'so-far'
        """
        if self.size is not None:
            return self.size
        return "memory" if any(load.cycle() is not None for load in loads) else "so-far"

    @property
    def smallest(self) -> float:
        """The smallest step an adaptive run may take (s)."""
        return self.dt_min if self.dt_min is not None else self.dt * DT_MIN_FRACTION

    @property
    def steps(self) -> int:
        return int(round(self.end / self.dt))

    def memory_time(self, loads: Sequence[PressureLoad]) -> float:
        """W (s): ``memory`` when set, else the shortest period of the ``loads``, else ``end``.

        >>> from multilayer.functions.loads import ConstantPressure, SinePressure
        >>> time = TimeSpec(end=1.0, dt=1e-3, tolerance=1e-3)
        >>> time.memory_time([ConstantPressure(1.0)]), time.memory_time([SinePressure(1.0, 4.0), SinePressure(1.0, 5.0)])
        (1.0, 0.2)
        >>> attrs.evolve(time, memory=0.5).memory_time([SinePressure(1.0, 5.0)])
        0.5
        """
        if self.memory is not None:
            return self.memory
        periods = [p for p in (load.cycle() for load in loads) if p is not None]
        return min(periods, default=self.end)


@attrs.frozen
class ModelSpec:
    """A plugin chosen by a case: where it was declared, its name, its parameters."""

    path: str  #: key path in the case file, e.g. ``layers[1]``
    model: str
    params: Mapping[str, Any] = attrs.field(factory=dict, eq=False)


@attrs.frozen
class LayerSpec(ModelSpec):
    thin: bool = True
    cells: int | None = None  #: radial cells of a thick band
    #: whether the built layer declares linear forms (``Layer.linear``): a coupler that needs a linear wall checks it
    linear: bool = True


@attrs.frozen
class Loads:
    inlet: BoundaryCondition  #: the condition at z = 0 (a boundary plugin)
    outlet: BoundaryCondition  #: the condition at z = L
    external: PressureLoad  #: P_e on the outer surface of the wall
    interface: PressureLoad  #: pressure on the lumen line when there is no fluid
    wall_motion: Formula | None = None  #: prescribed η(t, z) for a fluid with a moving rigid wall

    def histories(self) -> tuple[PressureLoad, ...]:
        """Every load the case prescribes as a function of t: the ends' (pressures, flow rates) and the wall's."""
        return (*self.inlet.histories(), *self.outlet.histories(), self.external, self.interface)

    def period(self) -> float | None:
        """The period T (s) with which the case's loads repeat: the longest period among the loads that repeat
        when each of the others divides it (to 1e-9), so that every periodic load repeats after T; None when no
        load repeats or two periods have no common cycle.  Loads that do not repeat (a constant) are left out.

        >>> from types import SimpleNamespace
        >>> from multilayer.functions.loads import ConstantPressure as C, SinePressure as S
        >>> E = lambda load: SimpleNamespace(histories=lambda: (load,))  # an end that prescribes one history
        >>> loads = lambda *p: Loads(E(p[0]), E(p[1]), C(0.0), C(0.0))
        >>> loads(S(1.0, 1.0), C(0.0)).period(), loads(S(1.0, 1.0), S(1.0, 3.0)).period(), loads(C(1.0), C(0.0)).period()
        (1.0, 1.0, None)
        >>> print(loads(S(1.0, 1.0), S(1.0, 1.5)).period())
        None
        """
        periods = [p for p in (load.cycle() for load in self.histories()) if p is not None]
        if not periods:
            return None
        longest = max(periods)
        if any(abs(longest / p - round(longest / p)) > 1e-9 * longest / p for p in periods):
            return None
        return longest


@attrs.frozen
class Initial:
    """Initial wall displacement and velocity, as formulas in (z, r); or, with ``pressure``, the fluid at rest at
    that uniform pressure (dyn/cm²) and the wall in static equilibrium under it
    (:mod:`multilayer.wall.equilibrium`); with ``prestress`` too, the wall on the mesh, its finite-strain layers
    on the stress-free reference that holds it there (:mod:`multilayer.wall.prestress`)."""

    displacement_z: Formula
    displacement_r: Formula
    velocity_z: Formula
    velocity_r: Formula
    pressure: float | None = None
    prestress: bool = False


@attrs.frozen
class Probe:
    name: str
    quantity: str
    z: float
    r: float | None = None
    line: int = 0  #: interface line (0 = lumen) for line quantities

    @property
    def place(self) -> str:
        """The name of a probe that has none: its quantity and place.

        >>> Probe("", "d_r", 3.0, 0.55).place, Probe("", "v", 3.0, line=1).place
        ('d_r_z3_r0.55', 'v_z3_line1')
        """
        r, line = self.r, self.line
        return f"{self.quantity}_z{self.z:g}" + (f"_r{r:g}" if r is not None else "") + (f"_line{line}" if line else "")


@attrs.frozen
class Output:
    every: int = 0  #: field snapshot cadence in steps (0: none)
    probes: tuple[Probe, ...] = ()


@attrs.frozen
class Limits:
    """When a run that has not crashed is stopped as failed anyway (``[solver]``)."""

    max_displacement: float = 0.5  #: |η| on the lumen, as a fraction of R
    energy_margin: float = 0.01  #: E − (E⁰ + work), as a fraction of max(|E⁰| + |work|, E)
    volume_margin: float = 0.05  #: |Σ volume residual|, as a fraction of the volume moved


@attrs.frozen(eq=False)
class FoundReference:
    """With ``[initial] prestress``, the stress-free reference of the finite-strain layers that validation found
    on the case's wall (:func:`multilayer.wall.prestress.prestress`), handed to the run's setup so that it is
    found once: the displacement D of the reference from the mesh (wall numbering), the counters of the static
    solves that found it, and what it was found from (:func:`reference_inputs`)."""

    displacement: np.ndarray
    stats: SolverStats
    inputs: tuple

    def serves(self, case: Case) -> bool:
        """Whether the reference is the one of ``case``'s wall: a case changed since validation (``attrs.evolve``
        of its layers, mesh, pressure, ...) has its own, found again."""
        return self.inputs == reference_inputs(case)


def reference_inputs(case: Case) -> tuple:
    """What the stress-free reference of ``case``'s wall depends on, comparable with ``==``: the geometry, the mesh
    along z, the layers (models, parameters, cells), the coupler (the lines it holds radially), whether a fluid
    pins the lumen's ends, ``initial.pressure`` and the external pressure at t = 0 (a spec's ``params`` take no
    part in its own equality: they are compared here)."""
    g = case.geometry
    return ((g.model, g.length, g.radius, dict(g.params)), (case.mesh.nz, case.mesh.order),
            tuple((spec.model, dict(spec.params), spec.cells) for spec in case.layers),
            (case.coupler.model, dict(case.coupler.params)), case.fluid is not None, case.initial.pressure,
            case.loads.external.value(0.0))


@attrs.frozen
class Case:
    title: str
    geometry: Geometry
    mesh: MeshSpec
    time: TimeSpec
    fluid: ModelSpec | None
    layers: tuple[LayerSpec, ...]
    coupler: ModelSpec
    loads: Loads
    initial: Initial
    output: Output
    solver: str = "superlu"
    #: when a changing matrix is refactorized (``[solver] reuse``)
    reuse: Reuse = Reuse()
    #: BLAS threads during a run (0: the libraries' defaults; ``[solver] threads``)
    threads: int = 1
    limits: Limits = Limits()
    #: the resolved case (defaults filled) as plain JSON-able data
    resolved: Mapping[str, Any] = attrs.field(factory=dict, eq=False)
    #: sha256 of the canonical JSON of ``resolved``
    digest: str = ""
    #: the folder relative file names of the case (table loads) are read from
    base_dir: str = attrs.field(default=".", eq=False)
    #: what validation found odd but not wrong, one line each: a plain number implausible in its key's CGS unit
    #: (``layers[1].young = 400: did you mean 400 kPa = 4e+06 dyn/cm²? ...``; :mod:`multilayer.plugin.units`)
    warnings: tuple[str, ...] = attrs.field(default=(), eq=False)
    #: with ``[initial] prestress``, the reference validation found for the wall (None: the setup finds it)
    reference: FoundReference | None = attrs.field(default=None, eq=False, repr=False)
