"""The convective boundary term of the open ends: static-pressure ends with backflow stabilization.

The step's advection is the skew-symmetric form (:mod:`multilayer_plugins.channel.forms`,
``advection_skew``), which relates to the convective one by integration by parts,

    advection_skew(u, q) = advection(u, q) + ½∫ (∇·a) u·q − ½ Σ_e ∫_Γe (a·n) u·q,

so an end that takes its pressure data P_e in the weak form without more
imposes, for the flow through it, the **total** pressure p + ½ρ_f|u|² ≈ P_e
(the seed's "dynamic pressure" condition): the kinetic energy the flow
carries through the end never enters the energy identity, in either
direction, and backflow cannot feed it (theory §10, "Open ends under
backflow"): ``[fluid] ends = "total-pressure"``.

``ends = "static-pressure"``, the default, adds on every open end of a Navier–Stokes fluid

    end_convection(ū, q) = ½ρ_f ∫_Γe J κ(a·n) ū·q,   κ(x) = x₊ + (1 − β) x₋,   x± = max/min(x, 0),

a = the scheme's extrapolation of uⁿ⁺¹ (the advecting velocity of the
step; the ends do not move along n, so w·n = 0 there).  With the skew form
this is the convective form with the do-nothing condition on static
pressure, p ≈ P_e where the flow leaves, plus the backflow term
−½ρ_f β ∫_Γe (a·n)₋ ū·q of Bazilevs et al. (2009) and Esmaily-Moghadam et
al. (2011) where it enters (β = 1: the directional do-nothing condition of
Braack & Mucha (2014)).  Tested with ū it gives the step's

    ½ρ_f Δt ∫_Γe J (a·n) |ū|²        (ledger column ``dissipation.<end>.convection``)
  + ½ρ_f Δt β ∫_Γe J |(a·n)₋| |ū|²   (``dissipation.<end>.backflow``, ≥ 0),

the kinetic energy the flow carries out through the end (negative where
backflow brings it in) and what the backflow term takes out of the flow
that comes in: their sum is ½ρ_f Δt ∫_Γe J [(a·n)₊ + (β − 1)|(a·n)₋|] |ū|²,
≥ 0 for β ≥ 1.  Both are quadratures of the fields at the facets' points,
not the matrix.  The term is linear in ū (a is lagged), in
the matrix (its facet entries are in the sparsity pattern from setup).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from skfem import BilinearForm, Functional

from multilayer_plugins.channel.forms import dot

#: what an end's pressure data prescribe (``[fluid] ends``; the first is the default)
END_PRESSURES = ("static-pressure", "total-pressure")


@BilinearForm
def end_convection(u, q, w):
    """∫_Γe J κ u·q on an end's facets, κ = κ(a·n) given at the facets' points  (× ½ρ_f)."""
    return dot((w.J * w.kappa) * u, q)


@Functional
def end_kinetic_flux(w):
    """∫_Γe J κ |u|² on an end's facets  (× ½ρ_f Δt: the term's share of the step's energy)."""
    return w.J * w.kappa * dot(w.u, w.u)


def backflow_part(flux: np.ndarray) -> np.ndarray:
    """(a·n)₋ ≤ 0: where the flow enters."""
    return np.minimum(flux, 0.0)


class _Facets:
    """One end's facet tables, built once: the velocity basis functions at the facets' points and their pair
    products with the quadrature weights, so that a step's term is one contraction with κ (the scikit-fem
    forms above define it; a facet assembly through them costs more than the rest of a step's fluid
    assembly, and the tests check the two agree)."""

    def __init__(self, basis: Any):
        #: the velocity DOF of each local function on each facet (functions × facets)
        self.dofs = np.asarray(basis.element_dofs)
        #: the functions' values at the points: (functions, component, facet, point)
        self.values = np.array([np.asarray(basis.basis[i][0]) for i in range(basis.Nbfun)])
        self.dx = np.asarray(basis.dx)
        #: φ_i·n at the points: (functions, facet, point)
        self.normal = np.einsum("icfq,cfq->ifq", self.values, np.asarray(basis.normals))
        #: φ_i·φ_j dx at the points: (functions, functions, facet, point)
        self.products = np.einsum("icfq,jcfq,fq->ijfq", self.values, self.values, self.dx)
        n = self.dofs.shape[0]
        #: (rows, columns) of the entries, in the order of :meth:`entries`
        self.rows = np.broadcast_to(self.dofs[:, None, :], (n, n, self.dofs.shape[1])).ravel()
        self.cols = np.broadcast_to(self.dofs[None, :, :], (n, n, self.dofs.shape[1])).ravel()

    def normal_velocity(self, a: np.ndarray) -> np.ndarray:
        """a·n at the points (facet, point)."""
        return np.einsum("if,ifq->fq", a[self.dofs], self.normal)

    def at_points(self, u: np.ndarray) -> np.ndarray:
        """u at the points (component, facet, point)."""
        return np.einsum("if,icfq->cfq", u[self.dofs], self.values)

    def entries(self, weight: np.ndarray) -> np.ndarray:
        """∫ weight φ_j·φ_i over the facets, for (rows, cols), ``weight`` at the points (facet, point)."""
        return np.einsum("ijfq,fq->ijf", self.products, weight).ravel()


class EndConvection:
    """The static-pressure ends' convective term on both ends of a channel.

    Parameters
    ----------
    bases : mapping
        Each end's facet basis (the velocity's, in the geometry's measure: ``Channel.inlet``, ``.outlet``).
    density : float
        ρ_f (g/cm³).
    backflow : float
        β ≥ 0, the strength of the backflow term (1: no kinetic energy comes in with the flow).
    """

    def __init__(self, bases: Mapping[str, Any], density: float, backflow: float):
        if not backflow >= 0.0:
            raise ValueError(f"the backflow coefficient β must be ≥ 0, got {backflow!r}")
        self.density = float(density)
        self.backflow = float(backflow)
        self.facets = {end: _Facets(b) for end, b in bases.items()}
        #: (rows, columns) of each end's entries (pairs of DOFs of a cell: in the velocity block's pattern)
        self.entries = {end: (f.rows, f.cols) for end, f in self.facets.items()}
        self._slots: dict[str, np.ndarray] = {}

    def place(self, pattern: Any) -> None:
        """Look up each end's slots in the step's pattern (once)."""
        self._slots = {end: pattern.slots(*entries) for end, entries in self.entries.items()}

    def normal_velocity(self, end: str, a: np.ndarray) -> np.ndarray:
        """a·n at the end's facet points (facet, point), for the velocity DOFs ``a``."""
        return self.facets[end].normal_velocity(a)

    def kappa(self, flux: np.ndarray) -> np.ndarray:
        """κ(a·n) = (a·n) − β(a·n)₋ = (a·n)₊ + (1 − β)(a·n)₋."""
        return flux - self.backflow * backflow_part(flux)

    def add_matrix(self, data: np.ndarray, a: np.ndarray, stretches: Mapping[str, float]) -> None:
        """data += ½ρ_f ∫_Γe J_e κ(a·n) ū·q on each end; ``stretches`` the ends' J_e (volume element)."""
        for end, facets in self.facets.items():
            kappa = self.kappa(facets.normal_velocity(a))
            np.add.at(data, self._slots[end], (0.5 * self.density * stretches[end]) * facets.entries(kappa))

    def ledger(self, ubar: np.ndarray, a: np.ndarray, stretches: Mapping[str, float], dt: float
               ) -> dict[str, float]:
        """The step's dissipation of the term on each end by column (module docstring): quadratures of ū and a
        at the facets' points (not the matrix)."""
        out = {}
        for end, facets in self.facets.items():
            flux = facets.normal_velocity(a)
            u = facets.at_points(ubar)
            weighted = (0.5 * self.density * dt * stretches[end]) * (u[0] ** 2 + u[1] ** 2) * facets.dx
            out[f"dissipation.{end}.convection"] = float(np.sum(weighted * flux))
            out[f"dissipation.{end}.backflow"] = self.backflow * float(np.sum(weighted * -backflow_part(flux)))
        return out
