"""The volume ledger of theory §7 ("Volume: the second ledger"), closed step by step beside the energy ledger.

Incompressibility makes the fluid's volume an invariant of every step: the
lumen's volume changes by what flows through the two ends,

    V(tⁿ⁺¹) − V(tⁿ) = −Δt (Q̄_inlet + Q̄_outlet),

Q̄_e the step's outward flux through end e (the fluid's ``end.<e>.Q``
columns, at the scheme's test level) and V the volume between the axis and
the lumen in the geometry's measure,

    V = ∫₀ᴸ A(R + η(ẑ)) (1 + ∂_ẑ d_z(ẑ)) dẑ,

A(ρ) the section's measure (:meth:`multilayer.geometry.contract.Geometry.section`:
ρ per unit depth, πρ² in a tube) and d_z the lumen's axial displacement
under no-slip at a thick band (0 otherwise).  η is the fluid domain's
(``State.eta``), integrated exactly by Gauss quadrature; the step's change
is formed without the cancellation of V^{n+1} − Vⁿ, so a scheme that keeps
the balance keeps it to round-off in the columns.

A step whose domain moves with the velocity the fluid has on the wall
keeps the balance; a partitioned step whose structure moves the lumen with
another velocity than the fluid's trace does not (theory §7, "Volume"), and
``[solver] volume_margin`` stops a run whose accumulated imbalance
(``volume.drift``) exceeds that fraction of the volume moved so far.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import attrs
import numpy as np
import scipy.sparse as sp
import skfem

from multilayer.coupling.contract import StepReport
from multilayer.coupling.kit import AXIAL
from multilayer.fluid.contract import ENDS
from multilayer.geometry.spaces import LineSpace
from multilayer.scene.state import State

#: a step's volume scale never below this fraction of the lumen's volume (round-off of V itself)
FLOOR = 1e-13


class LumenVolume:
    """The lumen's volume V(η, d_z) and its change between two states, on the fluid's interface line.

    >>> from multilayer.geometry.contract import Geometry
    >>> from multilayer.geometry.spaces import make_line_space
    >>> class Tube(Geometry):  # the measure of a tube, dV = 2πr dz dr
    ...     radial_power = 1
    ...     def weight(self, r):
    ...         return 2.0 * np.pi * np.asarray(r, dtype=float)
    >>> line = make_line_space(6.0, 10, 2, 0.3, Tube())
    >>> meter = LumenVolume(line)
    >>> eta = 0.01 * np.sin(np.pi * line.z / 6.0)   # P2 interpolant of a bulge
    >>> exact = np.pi * (0.3**2 * 6.0 + 2 * 0.3 * 0.01 * 12 / np.pi + 0.01**2 * 3.0)
    >>> abs(meter.volume(eta) - exact) / exact < 1e-5   # the interpolant's error, not the quadrature's
    True
    >>> abs(meter.change(np.zeros_like(eta), eta) - (meter.volume(eta) - meter.volume(0 * eta))) < 1e-14
    True
    """

    def __init__(self, line: LineSpace):
        self.line = line
        b = line.basis
        # exact for A(R + η)(1 + d_z'): degree (1 + k)·p + p − 1 in ẑ
        degree = (2 + line.geometry.radial_power) * line.order
        basis = skfem.CellBasis(b.mesh, b.elem, intorder=degree + 1)
        self._dx = basis.dx
        n = line.ndofs
        cols = basis.element_dofs  # (local DOFs, elements)
        phi = np.array([np.asarray(basis.basis[i][0]) for i in range(cols.shape[0])])  # (local, elements, points)
        dphi = np.array([basis.basis[i][0].grad[0] for i in range(cols.shape[0])])
        self._value = _evaluator(cols, phi, n)
        self._slope = _evaluator(cols, dphi, n)
        self._shape = self._dx.shape

    def _at(self, eta: np.ndarray, eta_z: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | float]:
        rho = self.line.radius + (self._value @ eta).reshape(self._shape)
        stretch = 1.0 if eta_z is None else 1.0 + (self._slope @ eta_z).reshape(self._shape)
        return rho, stretch

    def volume(self, eta: np.ndarray, eta_z: np.ndarray | None = None) -> float:
        """V of the lumen displaced by η (and d_z): cm³ in a tube, cm² per unit depth in a planar channel."""
        rho, stretch = self._at(eta, eta_z)
        return float(np.sum(self._dx * self.line.geometry.section(rho) * stretch))

    def change(self, eta_old: np.ndarray, eta_new: np.ndarray, eta_z_old: np.ndarray | None = None,
               eta_z_new: np.ndarray | None = None) -> float:
        """V(new) − V(old), formed as ∫ [A(ρ₁) − A(ρ₀)](1 + s₁) + A(ρ₀)(s₁ − s₀) without cancelling V."""
        geometry = self.line.geometry
        rho0, _ = self._at(eta_old, eta_z_old)
        rho1, s1 = self._at(eta_new, eta_z_new)
        axial = 0.0
        if eta_z_old is not None or eta_z_new is not None:  # s₁ − s₀ from d_z's change, not from 1 + s each
            z0, z1 = (np.zeros_like(eta_old) if z is None else z for z in (eta_z_old, eta_z_new))
            axial = geometry.section(rho0) * (self._slope @ (z1 - z0)).reshape(self._shape)
        return float(np.sum(self._dx * (geometry.section_change(rho0, rho1) * s1 + axial)))


def _evaluator(cols: np.ndarray, values: np.ndarray, n: int):
    """The sparse matrix taking a line vector to its values (or slopes) at every quadrature point."""
    local, elements, points = values.shape
    rows = np.arange(elements * points).reshape(elements, points)
    r = np.broadcast_to(rows, (local, elements, points)).ravel()
    c = np.broadcast_to(cols[:, :, None], (local, elements, points)).ravel()
    return sp.csr_matrix((values.ravel(), (r, c)), shape=(elements * points, n))


def lumen(state: State) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(η, d_z) of the fluid's domain in ``state``: d_z only under no-slip at a thick band (``extra["eta_z"]``)."""
    return state.eta, state.extra.get(AXIAL[0])


@attrs.define
class VolumeLedger:
    """What the volume ledger carries from step to step: the accumulated imbalance, the volume moved, the worst
    step.  It is part of a checkpoint (through the tally), so a resumed run goes on with the same numbers.
    """

    margin: float  #: ``[solver] volume_margin``
    steps: int = 0  #: steps closed
    drift: float = 0.0  #: Σ residual (cm³, or cm² per unit depth)
    #: Σ of each step's volume moved: ½(|Σα_kV^{n+1−k}| + Δt|Q̄_inlet| + Δt|Q̄_outlet|), what enters being what
    #: leaves or is stored (so the relative residual of a step is at most 2)
    moved: float = 0.0
    max_rel: float = 0.0  #: the largest step residual relative to the volume its step moved

    def close(self, meter: LumenVolume, parts: Sequence[tuple[State, StepReport]]) -> dict[str, float]:
        """The step's columns ``volume.fluid``, ``volume.residual``, ``volume.relative_residual``, ``volume.drift``.

        ``parts`` are the (new state, report) of each stage of the step (:meth:`StepReport.parts
        <multilayer.coupling.contract.StepReport.parts>`: the step itself for a single-stage scheme).  A stage's
        residual is Σ α_k V^{n+1−k} + Δt (Q̄_inlet + Q̄_outlet), α its difference weights
        (``StepReport.alpha``: ΔV for a one-step rule), Δt its own, each V^{n+1−k} − Vⁿ formed by
        :meth:`LumenVolume.change`; its older levels are its state's (the oldest repeated, as the scheme
        pads them), its ``end.<end>.Q`` its report's diagnostics (a closed end passes nothing).  The step's
        residual and the volume it moved are its stages' summed.
        """
        residual = scale = 0.0
        for new, report in parts:
            stage_residual, stage_scale = self._stage(meter, new, report.alpha, report.diagnostics)
            residual, scale = residual + stage_residual, scale + stage_scale
        volume = meter.volume(*lumen(parts[-1][0]))
        scale = max(scale, FLOOR * abs(volume))
        self.steps += 1
        self.drift += residual
        self.moved += scale
        relative = abs(residual) / scale if scale > 0.0 else 0.0
        self.max_rel = max(self.max_rel, relative)
        return {"volume.fluid": volume, "volume.residual": residual, "volume.relative_residual": relative,
                "volume.drift": self.drift}

    @staticmethod
    def _stage(meter: LumenVolume, new: State, alpha: Sequence[float],
               columns: Mapping[str, float]) -> tuple[float, float]:
        """(residual, volume moved) of one stage: Σα_k V^{n+1−k} + Δt Σ_e Q̄_e, ½(|Σα_kV^{n+1−k}| + Δt Σ_e |Q̄_e|)."""
        states = new.history(len(alpha))
        old = states[1]
        eta_old, z_old = lumen(old)
        dt = new.t - old.t
        change = 0.0  # Σα_k V^{n+1−k} = Σ_{k≠1} α_k (V^{n+1−k} − Vⁿ), as Σα_k = 0
        for a, s in zip(alpha, states):
            if s is not old:
                eta, z = lumen(s)
                change += a * meter.change(eta_old, eta, z_old, z)
        fluxes = [dt * float(columns.get(f"end.{end}.Q", 0.0)) for end in ENDS]
        return change + sum(fluxes), 0.5 * (abs(change) + sum(abs(f) for f in fluxes))

    @property
    def relative_drift(self) -> float:
        """|Σ residual| over the volume moved (0 before anything moved)."""
        return abs(self.drift) / self.moved if self.moved > 0.0 else 0.0

    def excess(self, t: float, volume: float) -> str | None:
        """Why the run must stop when the accumulated imbalance exceeds ``margin`` of the volume moved, else None.

        Checked from step ⌈1/margin⌉ on: a first-order scheme whose wall lags
        the fluid by one step (the splitting's start from rest) is one step's
        flow behind, 1/n of what n steps moved, and that converges with Δt.
        """
        if self.steps < math.ceil(1.0 / self.margin):
            return None
        if self.relative_drift > self.margin and abs(self.drift) > FLOOR * abs(volume):
            return (
                f"volume not conserved at t = {t:.6g} s: the lumen's volume and the flow through its ends disagree "
                f"by {self.drift:.6g} after {self.moved:.6g} moved ({self.relative_drift:.3g} of it; "
                f"[solver] volume_margin = {self.margin:g}): the coupling loses fluid through the wall here "
                "(docs/theory.md, 'Volume'); a smaller Δt, or a coupler whose wall moves with the fluid "
                "('monolithic', or 'kinematic-splitting' with its default robin = 'impedance')")
        return None

    def summary(self) -> dict[str, float]:
        """The ``volume`` block of ``summary.json``."""
        return {"max_relative_residual": self.max_rel, "drift": self.drift, "moved": self.moved,
                "relative_drift": self.relative_drift}

    def to_data(self) -> dict[str, float]:
        return {"margin": float(self.margin), "steps": int(self.steps), "drift": float(self.drift),
                "moved": float(self.moved), "max_rel": float(self.max_rel)}

    @classmethod
    def from_data(cls, data: object) -> VolumeLedger:
        """The ledger from :meth:`to_data`'s numbers, refused (ValueError) unless exactly those, finite."""
        keys = {"margin", "drift", "moved", "max_rel"}
        if (not isinstance(data, dict) or set(data) != {*keys, "steps"} or not isinstance(data["steps"], int)
                or not all(isinstance(data[k], float) and math.isfinite(data[k]) for k in keys)):
            raise ValueError("the tally's volume ledger should have the finite numbers " + ", ".join(sorted(keys))
                             + " and the whole number steps")
        return cls(data["margin"], data["steps"], data["drift"], data["moved"], data["max_rel"])


__all__ = ["LumenVolume", "VolumeLedger"]
