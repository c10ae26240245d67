"""What a case needs — unknowns, memory, steps — against what the machine has.

A case that cannot run is refused before any work starts.  The unknowns
are counted exactly from the meshes (:mod:`multilayer.geometry.mesh`: ``nz`` cells
along z, each rectangle cut into two triangles):

* fluid, Taylor–Hood P2/P1 (order 2): ``2 (2nz+1)(2nr+1) + (nz+1)(nr+1)``;
  MINI P1b/P1 (order 1): ``2 ((nz+1)(nr+1) + 2 nz nr) + (nz+1)(nr+1)``;
* wall with thick bands of C radial cells in all: vector Lagrange,
  ``2 (p nz + 1)(p C + 1)`` for order p; thin layers only: the lumen
  line, ``p nz + 1``.

The memory of N unknowns is estimated as

    :data:`BASELINE` + N · :data:`BYTES_PER_DOF` · max(1, (N / :data:`DOFS_MEASURED`)^:data:`GROWTH`)

from the peak resident memory of coupled runs (the matrices, their sparse
LU factorizations, the assembly's work arrays) measured with
``python scripts/memory_per_dof.py`` at four mesh sizes, and of the 10⁶-unknown
run (``docs/case-files.md``, "Size limits"): :data:`BYTES_PER_DOF` is the
most any run up to :data:`DOFS_MEASURED` unknowns took per unknown, rounded
up (it is flat there: 6–11 kB from 4k to 297k unknowns), and :data:`GROWTH`
the exponent of its growth from 297k to 1.15M unknowns (0.024: the factors'
fill per row grows like log N on the nested-dissection ordering of
:mod:`multilayer.numerics.ordering`), rounded up.  Every measured run lies below the estimate.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs

from multilayer.case.model import DT_MIN_FRACTION
from multilayer.case.schema import ADAPTIVE_KEYS, MAX_STEPS, STEPS_TOL
from multilayer.plugin.problems import Problem

#: Peak memory of a run per unknown (bytes) at :data:`DOFS_MEASURED` unknowns, measured and rounded up.
BYTES_PER_DOF = 11_000
#: Up to this many unknowns the memory per unknown was measured flat (``pulse-koiter-thick`` at 480 x 64,
#: order 2: 296 501 unknowns, rounded up); beyond it, it grows like N^:data:`GROWTH` (measured to 1.15M).
DOFS_MEASURED = 300_000
#: Exponent of the growth of the memory per unknown beyond :data:`DOFS_MEASURED`, measured and rounded up.
GROWTH = 0.05
#: Resident memory of the process before a run (Python, numpy, scipy, scikit-fem), measured and rounded up.
BASELINE = 100e6

GB = 1e9


def fluid_dofs(nz: int, nr: int, order: int) -> int:
    """Unknowns of the channel fluid: velocity (2 components) and P1 pressure.

    >>> fluid_dofs(6, 2, 2), fluid_dofs(6, 2, 1)
    (151, 111)
    """
    vertices = (nz + 1) * (nr + 1)
    if order == 2:
        return 2 * (2 * nz + 1) * (2 * nr + 1) + vertices
    return 2 * (vertices + 2 * nz * nr) + vertices  # P1 and one bubble per triangle


def wall_dofs(nz: int, order: int, band_cells: Sequence[int] = ()) -> int:
    """Unknowns of the wall: the lumen line alone, or (d_z, d_r) on every band.

    ``band_cells`` are the radial cells of each thick band (none: thin layers only).

    >>> wall_dofs(6, 2), wall_dofs(6, 2, [4, 2])
    (13, 338)
    """
    cells = sum(band_cells)
    if cells == 0:
        return order * nz + 1
    return 2 * (order * nz + 1) * (order * cells + 1)


@attrs.frozen
class Need:
    """What a case needs: its unknowns by part and the memory they take."""

    fluid: int = 0
    wall: int = 0

    @property
    def dofs(self) -> int:
        return self.fluid + self.wall

    @property
    def memory(self) -> float:
        """Bytes, estimated (see the module docstring)."""
        n = float(self.dofs)
        return BASELINE + n * BYTES_PER_DOF * max(1.0, n / DOFS_MEASURED) ** GROWTH


def need(nz: int, nr: int, order: int, fluid: bool, wall: bool, band_cells: Sequence[int] = ()) -> Need:
    """The unknowns and memory of a scene.

    >>> n = need(60, 8, 2, fluid=True, wall=True, band_cells=[4])
    >>> n.fluid, n.wall, gigabytes(n.memory)
    (4663, 2178, '0.18 GB')
    >>> gigabytes(need(10**9, 8, 2, fluid=True, wall=True, band_cells=[4]).memory)
    '2.4e+06 GB'
    """
    return Need(fluid_dofs(nz, nr, order) if fluid else 0, wall_dofs(nz, order, band_cells) if wall else 0)


def available_memory(meminfo: Path | str = "/proc/meminfo") -> float | None:
    """Bytes of memory available to a new process (Linux ``MemAvailable``), or None when unknown.

    Falls back on the free physical pages where ``/proc/meminfo`` is missing.
    """
    try:
        for line in Path(meminfo).read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return float(line.split()[1]) * 1024.0  # kB
    except (OSError, ValueError, IndexError):
        pass
    try:
        return float(os.sysconf("SC_AVPHYS_PAGES")) * float(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return None


def gigabytes(n: float) -> str:
    """A size for a message: ``23 GB``, ``0.27 GB``, ``9.1e+05 GB``.

    >>> gigabytes(23.4e9), gigabytes(2.7e8), gigabytes(9.1e14)
    ('23 GB', '0.27 GB', '9.1e+05 GB')
    """
    g = n / GB
    return f"{g:.0f} GB" if 10 <= g < 1e4 else f"{g:.2g} GB"


def steps_problems(time: Mapping[str, float]) -> list[Problem]:
    """A run of too many steps (beyond :data:`MAX_STEPS`), or ``time.end`` not a whole number of steps;
    with ``time.tolerance`` (adaptive steps) the bounds of the step instead (:func:`adaptive_problems`)."""
    if "end" not in time or "dt" not in time:
        return []
    if time.get("tolerance") is not None:
        return adaptive_problems(time)
    unused = [Problem(f"time.{key}", time[key], "read only with adaptive steps", "set time.tolerance, or remove it")
              for key in ADAPTIVE_KEYS if time.get(key) is not None]
    if unused:
        return unused
    steps = time["end"] / time["dt"]
    if not steps <= MAX_STEPS:  # also end/dt = inf
        return [Problem("time.dt", time["dt"], f"{steps:.3g} steps to time.end = {time['end']:g}; expected at most "
                        f"{MAX_STEPS:.0e} steps", "is dt in seconds?")]
    if round(steps) < 1 or abs(steps - round(steps)) > STEPS_TOL * max(1.0, steps):
        return [Problem("time.end", time["end"], f"expected a whole number (>= 1) of steps dt = {time['dt']:g}",
                        f"end/dt = {steps:.6g}")]
    return []


def adaptive_problems(time: Mapping[str, float]) -> list[Problem]:
    """The bounds of adaptive steps: dt_min ≤ dt ≤ dt_max, at most :data:`MAX_STEPS` steps of dt_min.

    >>> print(*adaptive_problems({"end": 1.0, "dt": 1e-3, "tolerance": 1e-3, "dt_min": 1e-2, "dt_max": 1e-4}))
    time.dt_min = 0.01: expected at most time.dt_max = 0.0001
    >>> adaptive_problems({"end": 1.0, "dt": 1e-3, "tolerance": 1e-3, "dt_min": 1e-4})
    []
    """
    lo, hi, dt = time.get("dt_min"), time.get("dt_max"), time["dt"]
    if lo is not None and hi is not None and lo > hi:
        return [Problem("time.dt_min", lo, f"expected at most time.dt_max = {hi:g}")]
    if lo is not None and dt < lo:
        return [Problem("time.dt", dt, f"expected at least time.dt_min = {lo:g} (the first step)")]
    if hi is not None and dt > hi:
        return [Problem("time.dt", dt, f"expected at most time.dt_max = {hi:g} (the first step)")]
    if lo is not None and not time["end"] / lo <= MAX_STEPS:
        return [Problem("time.dt_min", lo, f"{time['end'] / lo:.3g} steps of it to time.end = "
                        f"{time['end']:g}; expected at most {MAX_STEPS:.0e}", "set a larger time.dt_min")]
    interval, smallest = time.get("output_interval"), lo if lo is not None else dt * DT_MIN_FRACTION
    if interval is not None and interval < smallest:  # the steps land on its multiples: none may be that short
        return [Problem("time.output_interval", interval, f"expected at least the smallest step, "
                        f"time.dt_min = {smallest:g} s (the steps land on its multiples)")]
    return []


def size_problems(mesh: Mapping[str, Any], fluid: bool, layers: Sequence[Any]) -> list[Problem]:
    """A case whose unknowns would not fit in the machine's available memory.

    The problem is reported at the largest of the size keys (``mesh.nz``,
    ``mesh.nr``, a band's ``cells``); ``layers`` are the case's layer specs.
    """
    if not {"nz", "nr", "order"} <= mesh.keys():
        return []
    bands = [layer for layer in layers if not layer.thin and layer.cells is not None]
    needed = need(mesh["nz"], mesh["nr"], mesh["order"], fluid=fluid, wall=bool(layers),
                  band_cells=[layer.cells for layer in bands])
    available = available_memory()
    if available is None or needed.memory <= available:
        return []
    sizes = [("mesh.nz", mesh["nz"])] + ([("mesh.nr", mesh["nr"])] if fluid else [])
    sizes += [(f"{layer.path}.cells", layer.cells) for layer in bands]
    path, value = max(sizes, key=lambda item: item[1])
    parts = ", ".join(f"{part} {n:.3g}" for part, n in (("fluid", needed.fluid), ("wall", needed.wall)) if n)
    return [Problem(
        path, value,
        f"the case needs about {gigabytes(needed.memory)} of memory ({needed.dofs:.3g} unknowns: {parts}), "
        f"this machine has {gigabytes(available)} available",
        "use a coarser mesh (see docs/case-files.md, Size limits)")]
