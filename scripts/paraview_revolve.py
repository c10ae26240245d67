"""Follow docs/case-files.md's ParaView recipe on a tube's snapshots, in ParaView itself, and check what it draws.

Run with ParaView's batch interpreter (Debian: ``apt install python3-paraview``):

    pvbatch scripts/paraview_revolve.py RUN_DIR [RESOLUTION ...]

on a run folder of an ``axisymmetric`` case with snapshots (``[output]
every > 0``).  For the last fluid snapshot it applies the recipe's filters —
*Transform* (Rotate (0, −90, 0), Transform All Input Vectors),
*Extract Surface*, *Rotational Extrusion* (Angle 360) — at each resolution
(default 64, 256, 1024) and prints one JSON line with

* ``measure_integral``: *Integrate Variables* of ``measure`` on the meridian,
  ∫ 2πr dz dr, the lumen's volume as the run measures it;
* ``volume`` per resolution: the volume the revolved surface encloses (the
  divergence theorem over its triangles, each oriented outward: away from the
  axis on the wall, ∓z on the two end discs), which approaches
  ``measure_integral`` as the resolution grows (inscribed polygons: error
  ∝ 1/resolution²);
* ``axis_to_z``: the Transform sends a point (z, r, 0) to (0, r, z) and a
  velocity (u_z, u_r, 0) to (0, u_r, u_z), both to round-off;
* ``wall_to_z``: for the last wall snapshot, *Warp By Vector* on
  ``displacement`` then the Transform put a reference point (ẑ, r̂, 0) at
  (0, r̂ + d_r, ẑ + d_z), to round-off (relative to the largest coordinate).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from paraview.simple import (
    ExtractSurface,
    IntegrateVariables,
    RotationalExtrusion,
    Transform,
    Triangulate,
    WarpByVector,
    XMLUnstructuredGridReader,
    servermanager,
)
from vtkmodules.numpy_interface import dataset_adapter as dsa
from vtkmodules.vtkCommonCore import vtkIdList

VTK_TRIANGLE = 5


def fetch(proxy):
    """The proxy's output as a wrapped VTK data object."""
    return dsa.WrapDataObject(servermanager.Fetch(proxy))


def rotated(source):
    """The recipe's step 1: the vessel axis z becomes ParaView's Z axis."""
    t = Transform(Input=source)
    t.Transform = "Transform"
    t.Transform.Rotate = [0.0, -90.0, 0.0]
    t.TransformAllInputVectors = 1
    return t


def enclosed_volume(poly) -> float:
    """Volume inside a revolved meridian: Σ a·(b × c)/6 over its triangles, each turned outward."""
    ids, tris = vtkIdList(), []
    for i in range(poly.GetNumberOfCells()):
        if poly.GetCellType(i) == VTK_TRIANGLE:
            poly.GetCellPoints(i, ids)
            tris.append([ids.GetId(k) for k in range(3)])
    P = np.asarray(dsa.WrapDataObject(poly).Points)
    a, b, c = (P[np.asarray(tris)[:, k]] for k in range(3))
    n = np.cross(b - a, c - a)
    centroid = (a + b + c) / 3.0
    z0, z1 = P[:, 2].min(), P[:, 2].max()
    span = 1e-9 * max(z1 - z0, 1.0)
    outward = np.where(np.abs(centroid[:, 2] - z0) < span, -n[:, 2],
                       np.where(np.abs(centroid[:, 2] - z1) < span, n[:, 2],
                                n[:, 0] * centroid[:, 0] + n[:, 1] * centroid[:, 1]))
    return float(np.sum(np.sign(outward) * np.einsum("ij,ij->i", a, np.cross(b, c))) / 6.0)


def revolve(source, resolutions) -> dict:
    """Integrate Variables of ``measure`` on the meridian, and the recipe's revolved volume per resolution."""
    integral = float(fetch(IntegrateVariables(Input=source)).PointData["measure"][0])
    surface = ExtractSurface(Input=rotated(source))
    volumes = {}
    for resolution in resolutions:
        extrusion = RotationalExtrusion(Input=surface)
        extrusion.Angle = 360.0
        extrusion.Resolution = resolution
        extrusion.Capping = 0
        volumes[resolution] = enclosed_volume(servermanager.Fetch(Triangulate(Input=extrusion)))
    return {"measure_integral": integral, "volume": volumes}


def main(run: Path, resolutions) -> dict:
    fluid = XMLUnstructuredGridReader(FileName=[str(sorted(run.glob("fluid_*.vtu"))[-1])])
    meridian, turned = fetch(fluid), fetch(rotated(fluid))
    P0, P1 = np.asarray(meridian.Points), np.asarray(turned.Points)
    u0, u1 = np.asarray(meridian.PointData["velocity"]), np.asarray(turned.PointData["velocity"])
    scale = max(np.abs(P0).max(), 1e-300), max(np.abs(u0).max(), 1e-300)
    axis = max(np.abs(P1 - P0[:, [2, 1, 0]]).max() / scale[0], np.abs(u1 - u0[:, [2, 1, 0]]).max() / scale[1])
    out = {"snapshot": fluid.FileName[0], **revolve(fluid, resolutions), "axis_to_z": float(axis)}
    walls = sorted(run.glob("wall_*.vtu"))
    if walls:
        wall = XMLUnstructuredGridReader(FileName=[str(walls[-1])])
        warped = WarpByVector(Input=wall)
        warped.Vectors = ["POINTS", "displacement"]
        reference = fetch(wall)
        expected = (np.asarray(reference.Points) + np.asarray(reference.PointData["displacement"]))[:, [2, 1, 0]]
        placed = np.asarray(fetch(rotated(warped)).Points)
        out["wall_to_z"] = float(np.abs(placed - expected).max() / max(np.abs(expected).max(), 1e-300))
    return out


if __name__ == "__main__":
    print(json.dumps(main(Path(sys.argv[1]), [int(r) for r in sys.argv[2:]] or [64, 256, 1024])))
