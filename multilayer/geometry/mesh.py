"""Structured meshes shared by every field: one z-partition, bands stacked in r.

All fields of a scene use the same ``nz`` cells along z, so the DOFs of a
thin layer on an interface line coincide with the radial DOFs of the fluid
and of the thick bands on that line (theory §3): no interpolation, no mortar.
"""

from __future__ import annotations

import numpy as np
import skfem


def z_nodes(length: float, nz: int) -> np.ndarray:
    """The shared z-partition: ``nz`` equal cells on (0, L).

    >>> z_nodes(6.0, 3)
    array([0., 2., 4., 6.])
    """
    return np.linspace(0.0, length, nz + 1)


def graded_nodes(r0: float, r1: float, cells: int, grading: float = 1.0) -> np.ndarray:
    """Nodes on [r0, r1], refined toward r1 for ``grading`` > 1 (uniform at 1).

    r = r0 + (r1 − r0) (1 − (1 − s)^grading), s uniform on [0, 1].

    >>> graded_nodes(0.0, 1.0, 2)
    array([0. , 0.5, 1. ])
    >>> bool(np.all(np.diff(graded_nodes(0.0, 1.0, 8, 2.0)) > 0))
    True
    """
    s = np.linspace(0.0, 1.0, cells + 1)
    r = r0 + (r1 - r0) * (1.0 - (1.0 - s) ** grading)
    r[0], r[-1] = r0, r1
    return r


def channel_mesh(length: float, radius: float, nz: int, nr: int, grading: float = 1.0) -> skfem.MeshTri:
    """The reference fluid domain Ω̂ = (0, L) × (0, R), coordinates (z, r)."""
    return skfem.MeshTri.init_tensor(z_nodes(length, nz), graded_nodes(0.0, radius, nr, grading))


def wall_mesh(length: float, radius: float, nz: int, bands: list[tuple[float, int]]) -> tuple[skfem.MeshTri, list[np.ndarray], list[float]]:
    """One conforming mesh of all thick bands, stacked outward from r = R.

    ``bands`` is a list of (thickness H, radial cells).  Returns the mesh,
    the element indices of each band and the radius of every band boundary
    (``len(bands) + 1`` values, the first R).
    """
    edges = [radius]
    rs = [np.array([radius])]
    for thickness, cells in bands:
        r0 = edges[-1]
        edges.append(r0 + thickness)
        rs.append(np.linspace(r0, r0 + thickness, cells + 1)[1:])
    mesh = skfem.MeshTri.init_tensor(z_nodes(length, nz), np.concatenate(rs))
    rc = mesh.p[1, mesh.t].mean(axis=0)
    elements = [np.flatnonzero((rc > a) & (rc < b)) for a, b in zip(edges[:-1], edges[1:])]
    return mesh, elements, edges


def line_mesh(length: float, nz: int) -> skfem.MeshLine:
    """The z-partition as a 1D mesh, for thin layers."""
    return skfem.MeshLine(z_nodes(length, nz))


def lagrange_tri(order: int) -> skfem.Element:
    """Scalar Lagrange triangle of ``order`` 1 or 2."""
    return {1: skfem.ElementTriP1, 2: skfem.ElementTriP2}[order]()


def lagrange_line(order: int) -> skfem.Element:
    """Scalar Lagrange segment of ``order`` 1 or 2."""
    return {1: skfem.ElementLineP1, 2: skfem.ElementLineP2}[order]()


def match_by_z(z_target: np.ndarray, z_source: np.ndarray, scale: float) -> np.ndarray:
    """Indices ``i`` with ``z_source[i] == z_target`` (to round-off), one per target.

    >>> match_by_z(np.array([0.0, 2.0, 1.0]), np.array([1.0, 0.0, 2.0]), 2.0)
    array([1, 2, 0])
    """
    order = np.argsort(z_source)
    pos = np.searchsorted(z_source[order], z_target)
    pos = np.clip(pos, 0, len(z_source) - 1)
    left = np.clip(pos - 1, 0, len(z_source) - 1)
    pick = np.where(
        np.abs(z_source[order][left] - z_target) < np.abs(z_source[order][pos] - z_target), left, pos
    )
    idx = order[pick]
    if np.max(np.abs(z_source[idx] - z_target), initial=0.0) > 1e-9 * scale:
        raise ValueError("DOF locations on the interface line do not coincide")
    return idx
