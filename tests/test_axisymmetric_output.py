"""Snapshots of a tube carry its measure (docs/case-files.md, "Snapshots of a tube"); its summary its units.

A fluid snapshot of an axisymmetric run is the deformed meridian with the
point field ``measure`` = 2πr.  Integrated over the meridian's triangles
(exactly: it is linear), it is the volume of the revolved polygonal lumen,
which the frusta under the wall's polyline give independently (Pappus:
∫ 2πr dA = 2π r̄ A per triangle).  Planar snapshots stay as they were, without it.
"""

import json
import shutil
import subprocess
from pathlib import Path

import meshio
import numpy as np
import pytest
from runs import run_cli

SCRIPTS = Path(__file__).resolve().parents[1] / "scripts"


def triangle_integral(mesh, values):
    """∫ f dz dr over the triangles of a meridian snapshot for a linear f (vertex average × area)."""
    t = mesh.cells_dict["triangle"]
    p = mesh.points[:, :2]
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1]))
    return float(np.sum(area * values[t].mean(axis=1)))


def frusta(points):
    """The volume of revolution under the wall's polyline: Σ π Δz (r₁² + r₁r₂ + r₂²)/3."""
    top = points[np.argsort(points[:, 0])]
    z, r = top[:, 0], top[:, 1]
    return float(np.sum(np.pi * np.diff(z) * (r[:-1] ** 2 + r[:-1] * r[1:] + r[1:] ** 2) / 3.0))


def test_a_tube_snapshot_carries_its_measure_and_integrates_to_the_lumen_volume(tmp_path):
    out = tmp_path / "tube"
    code, _, _ = run_cli("pulse-koiter-thick-axisymmetric", out, "mesh.nz=12", "mesh.nr=3", "time.end=0.003",
                         "time.dt=1e-4", "output.every=30", 'coupler={model="monolithic",scheme="crank-nicolson"}')
    assert code == 0
    assert json.loads((out / "summary.json").read_text())["units"] == {"energy": "erg", "flow_rate": "cm³/s"}
    fluid = meshio.read(out / "fluid_000030.vtu")
    r = fluid.points[:, 1]
    assert np.allclose(fluid.point_data["measure"], 2 * np.pi * r, rtol=1e-14)
    # the wall's vertices: the outermost point of each column of vertices (one column per z node)
    z = np.round(fluid.points[:, 0], 12)
    top = np.array([fluid.points[z == zz][np.argmax(r[z == zz])] for zz in np.unique(z)])
    R, L = 0.5, 6.0
    assert np.max(top[:, 1]) > R  # the wall has moved
    volume = triangle_integral(fluid, fluid.point_data["measure"])
    assert abs(volume - frusta(top[:, :2])) < 1e-12 * np.pi * R**2 * L
    wall = meshio.read(out / "wall_000030.vtu")
    assert np.allclose(wall.point_data["measure"], 2 * np.pi * wall.points[:, 1], rtol=1e-14)


@pytest.mark.skipif(shutil.which("pvbatch") is None, reason="ParaView's pvbatch is not installed")
def test_the_paraview_recipe_revolves_the_lumen_the_run_measured(tmp_path):
    """docs/case-files.md's recipe, run in ParaView (scripts/paraview_revolve.py under pvbatch).

    The Transform puts (z, r, 0) at (0, r, z) and turns (u_z, u_r, 0) the same
    way, to round-off; a warped wall point lands at (0, r̂ + d_r, ẑ + d_z).  The
    revolved lumen's volume approaches the meridian's ∫ measure as the
    resolution n grows, like an inscribed n-gon, 1 − sin(2π/n)/(2π/n) ≈ (2π/n)²/6:
    measured 1.6056e-3, 1.0052e-4, 6.248e-6 relative at n = 64, 256, 1024
    (ParaView 5.11, this run), against (2π/n)²/6 = 1.6064e-3, 1.0040e-4,
    6.275e-6: within 0.5 %.
    """
    out = tmp_path / "tube"
    code, _, _ = run_cli("pulse-koiter-thick-axisymmetric", out, "mesh.nz=12", "mesh.nr=3", "time.end=0.003",
                         "time.dt=1e-4", "output.every=30", 'coupler={model="monolithic",scheme="crank-nicolson"}')
    assert code == 0
    done = subprocess.run(["pvbatch", str(SCRIPTS / "paraview_revolve.py"), str(out), "64", "256", "1024"],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["axis_to_z"] < 1e-14 and result["wall_to_z"] < 1e-14
    for n, volume in result["volume"].items():
        polygon = (2 * np.pi / int(n)) ** 2 / 6
        assert 0.95 * polygon < 1 - volume / result["measure_integral"] < 1.05 * polygon


def test_a_planar_snapshot_has_no_measure_field_and_its_units_are_per_unit_depth(tmp_path):
    code, _, _ = run_cli("pulse-koiter-thick", tmp_path / "planar", "mesh.nz=12", "mesh.nr=3", "time.end=0.0002",
                         "output.every=1")
    assert code == 0
    summary = json.loads((tmp_path / "planar" / "summary.json").read_text())
    assert summary["units"] == {"energy": "erg/cm", "flow_rate": "cm²/s"}
    for part in ("fluid", "wall"):
        assert "measure" not in meshio.read(tmp_path / "planar" / f"{part}_000001.vtu").point_data
