"""Abstract interfaces: Layer (thin or thick), Fluid, Coupler — and the spaces they see.

The core assembles any wall from the contributions of its layers without
knowing a concrete model.  A layer contributes

* its mass, damping and stiffness matrices (:class:`LayerMatrices`): these are
  its forms of SCHEME §3 A1 (ρ₁h ∫vψ, b₁, a₁ for a thin layer; ρ₂ ∫V·Ψ, a_S for
  a thick one) and, through them, its energy terms of §4 (½vᵀMv kinetic,
  ½dᵀKd elastic, Δt vᵀCv dissipated);
* its essential boundary conditions (:meth:`Layer.essential_dofs`).

A thin layer lives on an interface line and is given a :class:`LineSpace`
(1D Lagrange on the z-partition; its DOFs are the radial DOFs of the fields
next to it).  A thick layer is a radial band and is given a :class:`BandSpace`
(vector Lagrange restricted to the band, in the numbering of the whole wall).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any, ClassVar

import attrs
import numpy as np
import scipy.sparse as sp

from multilayer.loads import is_zero

if TYPE_CHECKING:  # pragma: no cover
    import skfem

    from multilayer.case import Case
    from multilayer.scene import Scene


@attrs.frozen(eq=False)
class LayerMatrices:
    """Mass M, damping C and stiffness K of one layer (symmetric, sparse).

    The layer's energy terms follow from them:

    >>> import scipy.sparse as sp, numpy as np
    >>> m = LayerMatrices(sp.eye(2) * 2.0, sp.csr_matrix((2, 2)), sp.eye(2))
    >>> m.kinetic(np.array([1.0, 1.0])), m.elastic(np.array([1.0, 0.0]))
    (2.0, 0.5)
    """

    mass: sp.spmatrix
    damping: sp.spmatrix
    stiffness: sp.spmatrix

    def kinetic(self, v: np.ndarray) -> float:
        """½ vᵀ M v."""
        return 0.5 * float(v @ (self.mass @ v))

    def elastic(self, d: np.ndarray) -> float:
        """½ dᵀ K d."""
        return 0.5 * float(d @ (self.stiffness @ d))

    def dissipation(self, v: np.ndarray, dt: float) -> float:
        """Δt vᵀ C v: energy the layer's viscosity takes in one step."""
        return dt * float(v @ (self.damping @ v))

    def scattered(self, P: sp.spmatrix) -> LayerMatrices:
        """The same forms moved to another numbering: P A Pᵀ."""
        return LayerMatrices(
            (P @ self.mass @ P.T).tocsr(),
            (P @ self.damping @ P.T).tocsr(),
            (P @ self.stiffness @ P.T).tocsr(),
        )


@attrs.frozen(eq=False)
class LineSpace:
    """The 1D space of a thin layer on the interface line r = ``radius``.

    ``basis`` is a scikit-fem basis of 1D Lagrange elements (order of the
    scene) on the z-partition shared by every field of the scene.
    """

    basis: skfem.CellBasis
    radius: float
    length: float
    order: int

    @property
    def z(self) -> np.ndarray:
        """z coordinate of every DOF."""
        return self.basis.doflocs[0]

    @property
    def ndofs(self) -> int:
        return int(self.basis.N)

    @property
    def end_dofs(self) -> np.ndarray:
        """The DOFs at z = 0 and z = L."""
        tol = 1e-9 * self.length
        return np.flatnonzero((self.z < tol) | (self.z > self.length - tol))


@attrs.frozen(eq=False)
class BandSpace:
    """The space of a thick layer: the band ``r_inner < r < r_outer``.

    ``basis`` is a vector (d_z, d_r) Lagrange basis restricted to the band's
    elements; its numbering is that of the whole wall, so matrices assembled
    on it are already global.
    """

    basis: skfem.CellBasis
    r_inner: float
    r_outer: float
    length: float
    order: int

    @property
    def thickness(self) -> float:
        return self.r_outer - self.r_inner

    @property
    def dofs(self) -> np.ndarray:
        """Every DOF touched by the band."""
        return np.unique(self.basis.element_dofs)

    def side_dofs(self, side: str, component: str | None = None) -> np.ndarray:
        """DOFs on one side of the band: ``"z=0"``, ``"z=L"``, ``"inner"``, ``"outer"``.

        ``component`` is ``"z"``, ``"r"`` or ``None`` (both).
        """
        dofs = self.dofs
        z, r = self.basis.doflocs[:, dofs]
        tol = 1e-9 * max(self.length, self.r_outer)
        where = {
            "z=0": np.abs(z) < tol,
            "z=L": np.abs(z - self.length) < tol,
            "inner": np.abs(r - self.r_inner) < tol,
            "outer": np.abs(r - self.r_outer) < tol,
        }[side]
        picked = dofs[where]
        if component is None:
            return picked
        owned = self.basis.split_indices()[{"z": 0, "r": 1}[component]]
        return np.intersect1d(picked, owned)


class Layer(ABC):
    """A wall layer.  Subclass :class:`ThinLayer` or :class:`ThickLayer`."""

    thin: ClassVar[bool]

    @abstractmethod
    def forms(self, space: Any) -> LayerMatrices:
        """Mass, damping and stiffness on ``space``."""

    def essential_dofs(self, space: Any) -> np.ndarray:
        """DOFs held at zero (in the numbering of ``space``)."""
        return np.zeros(0, dtype=np.int64)


class ThinLayer(Layer):
    """A layer on an interface line; unknown: the radial displacement η(z)."""

    thin = True

    def essential_dofs(self, space: LineSpace) -> np.ndarray:
        """Ends pinned: η(0) = η(L) = 0."""
        return space.end_dofs

    def long_wave_stiffness(self, radius: float | None = None) -> float:
        """C0 (dyn/cm³): the k → 0 limit of the layer's stiffness, 0 if none.

        ``radius`` is the radius of the line the layer sits on, for models
        whose coefficients depend on it.
        """
        return 0.0


class ThickLayer(Layer):
    """A radial band of the wall; unknown: the displacement d = (d_z, d_r)."""

    thin = False
    #: radial extent H of the band (cm)
    thickness: float

    def essential_dofs(self, space: BandSpace) -> np.ndarray:
        """Ends clamped: d = 0 at z = 0 and z = L."""
        return np.union1d(space.side_dofs("z=0"), space.side_dofs("z=L"))


class Fluid(ABC):
    """An incompressible fluid in the channel under the wall (SCHEME §3, step A2).

    The couplers rely on exactly these methods; ``multilayer_plugins.channel.model.ChannelFluid``
    implements them on the ALE reference channel.  Line vectors (η, v) are in
    the numbering of :attr:`line`, the interface line r = R shared with the wall.
    """

    density: float  #: ρ_f (g/cm³)
    viscosity: float  #: μ (poise)

    @abstractmethod
    def setup(self, length: float, radius: float, nz: int, nr: int, order: int = 2, grading: float = 1.0,
              dt: float = 1e-4, wall: str = "coupled", solver: str = "superlu",
              line: LineSpace | None = None) -> Any:
        """Discretize for a wall mode ``coupled``, ``rigid`` or ``prescribed``."""

    @property
    @abstractmethod
    def line(self) -> LineSpace:
        """The interface line whose DOFs are the fluid's wall u_r DOFs."""

    @abstractmethod
    def initial_state(self) -> Any:
        """The fluid at rest."""

    @abstractmethod
    def step(self, state: Any, eta: np.ndarray | None = None, v_half: np.ndarray | None = None,
             p_in: float = 0.0, p_out: float = 0.0, robin_mass: sp.spmatrix | None = None) -> Any:
        """One A2 step on the domain of ``eta`` with the wall velocity ``v_half``.

        Returns an object with ``state`` (its ``v`` the new wall velocity) and
        ``energy`` (the terms of the A2 identity).
        """

    @abstractmethod
    def kinetic_energy(self, state: Any, eta: np.ndarray | None = None) -> float:
        """½ρ_f ∫ J|u|² on the domain of ``eta``."""

    @abstractmethod
    def flow_rate(self, state: Any, eta: np.ndarray | None, z: float) -> float:
        """Volume flux through the section at z (cm²/s)."""

    @abstractmethod
    def probe(self, quantity: str, z: float, rhat: float | None = None) -> Any:
        """A function (state, η) → float for a probe, built once per run.

        ``u_z``, ``u_r``, ``p`` at the reference point (z, r̂) of the ALE map
        (it moves with the channel), or ``flow_rate`` through the section z.
        """

    @abstractmethod
    def velocity(self, state: Any, eta: np.ndarray | None, z, r) -> np.ndarray:
        """(u_z, u_r) at physical points, a (2, n) array."""

    @abstractmethod
    def pressure(self, state: Any, eta: np.ndarray | None, z, r) -> np.ndarray:
        """Pressure at physical points."""

    @abstractmethod
    def snapshot(self, state: Any, eta: np.ndarray | None = None) -> tuple:
        """(points (n, 2) in the deformed channel, triangles, point data)."""


@attrs.frozen
class StepReport:
    """What a coupler yields after each time step.

    ``ledger`` holds every energy-ledger term of the step (SCHEME §4) by
    column name, including ``energy.total`` and ``energy.residual``.
    """

    step: int
    t: float
    ledger: Mapping[str, float] = attrs.field(factory=dict)


class Coupler(ABC):
    """A time-stepping scheme that drives a scene."""

    #: the loads (keys of ``[loads]``) this coupler applies; any other must be left at 0
    loads: ClassVar[tuple[str, ...]] = ()

    def check_case(self, case: Case) -> list[str]:
        """Reasons this coupler cannot run ``case`` (empty when it can).

        Called by the case validator, so ``multilayer validate`` reports them.
        The default rejects a non-zero load that the coupler would ignore.
        """
        name = getattr(self, "name", type(self).__name__)
        return [f"loads.{key} is set, but {name} does not apply it (it applies: {', '.join(self.loads) or 'none'})"
                for key in ("inlet", "outlet", "external", "interface")
                if key not in self.loads and not is_zero(getattr(case.loads, key))]

    def prepare(self, scene: Scene) -> None:
        """Set up what the scheme needs before the first step (e.g. the fluid's wall mode).

        Called once, before the initial snapshot, so t = 0 is written for every part.
        """

    @abstractmethod
    def evolve(self, scene: Scene) -> Iterator[StepReport]:
        """Advance the scene step by step, yielding a report after each step."""
