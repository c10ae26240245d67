"""Measure the peak memory of a run per unknown: the constant of ``multilayer.case.resources``.

Runs a bundled coupled case (default ``cases/pulse-koiter-thick.toml``: Navier–Stokes,
a Koiter shell on a thick band) for a few steps at two or more mesh sizes,
each in a fresh process, and prints one JSON line per run:

* ``dofs``: the unknowns of the run (fluid + wall, from ``summary.json``);
* ``baseline_mb``: resident memory after imports and validation, before the run;
* ``peak_mb``: the process's peak resident memory (``ru_maxrss``);
* ``bytes_per_dof``: (peak − baseline) / dofs.

    python scripts/memory_per_dof.py                                   # the numbers of docs/case-files.md
    python scripts/memory_per_dof.py --meshes 60x8 240x32 --couplers kinematic-splitting monolithic --orders 1 2

Not a test: nothing is asserted.  ``multilayer.case.resources.BYTES_PER_DOF`` is
the largest ``bytes_per_dof`` measured, rounded up.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

CASE = Path(__file__).parents[1] / "cases" / "pulse-koiter-thick.toml"


def resident_bytes() -> float:
    """Current resident memory of this process (Linux ``VmRSS``)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return float(line.split()[1]) * 1024.0
    raise RuntimeError("no VmRSS in /proc/self/status")


def child(case: str, nz: int, nr: int, order: int, coupler: str, steps: int) -> None:
    """One run in this process; prints its JSON line."""
    from multilayer.case.casefile import load_case
    from multilayer.runner.loop import run_case

    loaded = load_case(case, [f"mesh.nz={nz}", f"mesh.nr={nr}", f"mesh.order={order}", f"coupler={coupler}",
                              "time.dt=1e-4", f"time.end={steps * 1e-4!r}", "output.every=0"])
    before = resident_bytes()
    with tempfile.TemporaryDirectory() as out:
        result = run_case(loaded, out)
        dofs = json.loads((Path(out) / "summary.json").read_text())["dofs"]
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024.0  # kB on Linux
    total = dofs.get("fluid", 0) + dofs.get("wall", 0)
    print(json.dumps({"mesh": f"{nz}x{nr}", "order": order, "coupler": coupler, "status": result.status,
                      "dofs": total, "baseline_mb": round(before / 1e6, 1), "peak_mb": round(peak / 1e6, 1),
                      "bytes_per_dof": round((peak - before) / total)}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", default=str(CASE))
    parser.add_argument("--meshes", nargs="+", default=["60x8", "240x32"], metavar="NZxNR")
    parser.add_argument("--orders", nargs="+", type=int, default=[2, 1])
    parser.add_argument("--couplers", nargs="+", default=["kinematic-splitting", "monolithic"])
    parser.add_argument("--steps", type=int, default=3)
    parser.add_argument("--child", nargs=5, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        nz, nr, order, coupler, steps = args.child
        child(args.case, int(nz), int(nr), int(order), coupler, int(steps))
        return
    for order in args.orders:
        for coupler in args.couplers:
            for mesh in args.meshes:
                nz, nr = mesh.split("x")
                subprocess.run([sys.executable, __file__, "--case", args.case, "--child", nz, nr, str(order),
                                coupler, str(args.steps)], check=True)


if __name__ == "__main__":
    main()
