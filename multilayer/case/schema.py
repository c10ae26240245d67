"""The schemas of a case file's core sections: their keys, types, bounds and defaults.

The plugins' own parameters are checked against the schemas the plugins register.
"""

from __future__ import annotations

from multilayer.case.ends import END_KEYS
from multilayer.numerics.linsolve import BACKENDS, FACTORS, REUSE_MODES, Reuse
from multilayer.plugin.problems import Problem
from multilayer.plugin.records import Param

#: More steps than this is a mistake (a time step in the wrong unit), not a run; also the bound of ``output.every``.
MAX_STEPS = 10**8
#: More layers than this is a mistake: the bound of a probe's interface ``line``.
MAX_LINES = 1000

SECTIONS = ("title", "geometry", "mesh", "time", "fluid", "layers", "coupler", "loads", "initial", "output", "solver",
            "sweep")

GEOMETRY = (
    Param("length", "L", "cm", gt=0.0, doc="channel length"),
    Param("radius", "R", "cm", gt=0.0, doc="reference radius of the lumen"),
    Param("model", type=str, default="planar", doc="the geometry plugin: what the (z, r) plane stands for"),
)
# mesh.nz, mesh.nr (and a band's cells) have no bound here: the memory check bounds them against the machine
# (multilayer.case.resources.size_problems), with a message that says how much memory they would need
MESH = (
    Param("nz", type=int, ge=1, doc="cells along z, shared by every field"),
    Param("nr", type=int, ge=1, doc="fluid cells across the lumen"),
    Param("order", type=int, choices=(1, 2), doc="polynomial order of every field"),
    Param("grading", default=1.0, ge=1.0, doc="fluid refinement toward the wall (1 = uniform)"),
)
#: how an adaptive run shares its tolerance among its steps (multilayer.coupling.clock)
CONTROLS = ("per-step", "per-unit-step")
#: what an adaptive run measures a field's error against: its size so far, or its size over the last memory time
SIZES = ("so-far", "memory")
TIME = (
    Param("end", "T", "s", gt=0.0, doc="final time"),
    Param("dt", "Δt", "s", gt=0.0, doc="time step (with tolerance: the first step)"),
    Param("tolerance", default=None, gt=0.0, lt=1.0,
          doc="adaptive steps: the relative error the run may accumulate in the wall's displacement and velocity "
              "and the fluid's velocity (each in the max norm over its DOFs, relative to its size: time.size); "
              "unset: every step is dt"),
    Param("dt_min", "", "s", default=None, gt=0.0,
          doc="adaptive steps: the smallest step; a step the error would make smaller stops the run"),
    Param("dt_max", "", "s", default=None, gt=0.0, doc="adaptive steps: the largest step"),
    Param("output_interval", "", "s", default=None, gt=0.0,
          doc="adaptive steps: a step lands on every multiple of it (snapshots are written there)"),
    Param("memory", "W", "s", default=None, gt=0.0,
          doc="adaptive steps: the span the tolerance is shared over (among its steps, or per unit of min(t, W)); "
              "unset: the loads' shortest period, or time.end when no load repeats"),
    Param("control", type=str, default=None, choices=CONTROLS,
          doc="adaptive steps: how the tolerance is shared among the steps: 'per-step' (every step of the span W the "
              "same local error: the fewest steps for an error that adds up; unset) or 'per-unit-step' (a step's "
              "local error in proportion to its length)"),
    Param("size", type=str, default=None, choices=SIZES,
          doc="adaptive steps: the size a field's error is relative to: 'so-far' (its peak so far, its rate "
              "counted over min(t, W); unset, without a periodic load) or 'memory' (its size over the last span W: "
              "its rate counted over W from the first step, its peak forgotten at the rate 1/W; unset, with one)"),
)
#: the keys of [time] that only adaptive steps (time.tolerance) read
ADAPTIVE_KEYS = ("dt_min", "dt_max", "output_interval", "memory", "control", "size")


#: radial cells of a thick layer: a core key, not a plugin parameter (its upper bound: the memory check)
CELLS = Param("cells", type=int, ge=1, default=4, doc="radial cells of a thick band")
WALL_LOAD_KEYS = ("external", "interface")
LOAD_KEYS = (*END_KEYS, *WALL_LOAD_KEYS)
QUANTITIES = ("eta", "v", "d_z", "d_r", "u_z", "u_r", "p", "flow_rate")
FLUID_QUANTITIES = ("u_z", "u_r", "p", "flow_rate")
LINE_QUANTITIES = ("eta", "v")
POINT_QUANTITIES = ("d_z", "d_r", "u_z", "u_r", "p")
PROBE = (
    Param("name", type=str, default=None, doc="column name in series.csv"),
    Param("quantity", type=str, choices=QUANTITIES, doc="what is measured"),
    Param("z", "z", "cm", doc="axial position"),
    Param("r", "r", "cm", default=None,
          doc="radial position in the reference configuration: Lagrangian in the wall, r̂ of the ALE map in the fluid"),
    Param("line", type=int, ge=0, le=MAX_LINES, default=None, doc="interface line of eta/v (0 = lumen)"),
)
INITIAL = (Param("pressure", "P⁰", "dyn/cm²", default=None,
                 doc="the fluid at rest at this uniform pressure and the wall in static equilibrium under it (and the "
                     "external pressure at t = 0); unset: the wall as initial.displacement gives it"),
           Param("prestress", type=bool, default=False,
                 doc="the case's geometry is the wall as imaged under initial.pressure: the finite-strain layers' "
                     "stress-free reference is found so that the wall under it sits on the mesh, and the run "
                     "starts there, in equilibrium (false: the geometry is the wall unloaded)"))
OUTPUT = (Param("every", type=int, ge=0, le=MAX_STEPS, default=0, doc="snapshot cadence in steps (0: none)"),)
SOLVER = (
    Param("linear", type=str, default="superlu", choices=tuple(BACKENDS), doc="sparse direct solver"),
    Param("reuse", type=str, default="krylov", choices=REUSE_MODES,
          doc="a changing matrix: 'krylov' (GMRES preconditioned by an earlier factorization) or 'none' "
              "(factorize every step)"),
    Param("max_iterations", type=int, default=Reuse().max_iterations, ge=1, le=1000,
          doc="GMRES iterations above which the preconditioner is refactorized (reuse = 'krylov')"),
    Param("tolerance", default=Reuse().tolerance, gt=0.0, lt=1.0,
          doc="relative residual a Krylov solve reaches (reuse = 'krylov')"),
    Param("factors", type=str, default=Reuse().factors, choices=FACTORS,
          doc="precision of a changing matrix's factorizations: 'double', or 'single' (half their memory, "
              "faster; every solve by GMRES on them to the same tolerance; SuperLU only)"),
    Param("factorization_cost", default=Reuse().factorization_cost, gt=0.0,
          doc="a factorization's cost in GMRES iterations: the iterations held factors cost beyond what they "
              "needed when young are added up, and at this sum they are replaced (reuse = 'krylov'; default: "
              "14 up to 70k unknowns, then growing like their square root; a very large value: only at "
              "max_iterations)"),
    Param("threads", type=int, default=1, ge=0, le=1024,
          doc="BLAS threads of numpy/scipy during a run (0: the libraries' defaults)"),
    Param("max_displacement", "", "R", default=0.5, gt=0.0,
          doc="stop the run when |η| on the lumen exceeds this fraction of R"),
    Param("energy_margin", default=0.01, gt=0.0,
          doc="stop the run when the energy exceeds initial energy + work by this fraction of their scale"),
    Param("volume_margin", default=0.05, gt=0.0,
          doc="stop the run when the lumen's volume and the flow through its ends disagree by this fraction of "
              "the volume moved so far (the volume ledger, volume.drift)"),
)


#: relative tolerance on end/dt being a whole number of steps
STEPS_TOL = 1e-6


#: Columns of ``series.csv`` a probe may not be named: the step, the time and the coupler's iteration count ...
RESERVED_COLUMNS = ("step", "t", "iterations", "dt", "landed")
#: ... and every column of the energy ledger and of the ends' and couplers' diagnostics, by its prefix.
RESERVED_PREFIXES = ("energy.", "kinetic.", "elastic.", "stored.", "work.", "dissipation.", "end.", "interface.",
                     "error.", "volume.")


def reserved_column(name: str) -> bool:
    """True when a probe named ``name`` would overwrite a column of ``series.csv`` the run writes itself.

    >>> [reserved_column(n) for n in ("t", "energy.total", "work.inlet", "eta_mid", "energy", "T")]
    [True, True, True, False, False, False]
    """
    return name in RESERVED_COLUMNS or name.startswith(RESERVED_PREFIXES)


def reserved_problem(path: str, name: str, instead: str) -> Problem:
    """The problem of a probe named like a column of ``series.csv`` (``instead``: a name it could have)."""
    reserved = ", ".join([*RESERVED_COLUMNS, *(f"{prefix}*" for prefix in RESERVED_PREFIXES)])
    return Problem(path, name, f"a column series.csv has already (reserved: {reserved})",
                   f"give the probe a name of its own, e.g. {instead!r}")
