"""The layer contract: what a wall layer gives the core (its forms on a space, and its essential DOFs).

A layer's forms on a space are its mass M, and the residual and tangent of
its forces at a state (displacement d, velocity v): the internal force
f(d) = ∇W(d) with its tangent K_T(d) = ∇²W(d) and stored energy W(d), the
damping force g(v) with its tangent C_T(v) and the power v·g(v) it takes.
A linear layer returns :class:`LayerMatrices` (M, C, K), from which they
follow: f = K d, K_T = K, W = ½dᵀKd, g = C v.  A nonlinear one returns a
subclass of :class:`NonlinearForms` whose damping and stiffness are its
tangents at rest, and which overrides ``elastic``, ``force`` and
``tangent`` (and ``damping_force``, ``damping_tangent`` when its damping is
nonlinear too).  The wall step solves every step by Newton's method
(:mod:`multilayer.numerics.newton`); for a linear wall that is one solve with
the factorization of its constant matrix.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

import attrs
import numpy as np
import scipy.sparse as sp

from multilayer.geometry.spaces import BandSpace, LineSpace


@attrs.frozen(eq=False)
class LayerMatrices:
    """Mass M, damping C and stiffness K of one layer (symmetric, sparse): a linear layer's forms.

    The layer's forces and energy terms follow from them:

    >>> import scipy.sparse as sp, numpy as np
    >>> m = LayerMatrices(sp.eye(2) * 2.0, sp.csr_matrix((2, 2)), sp.eye(2))
    >>> m.kinetic(np.array([1.0, 1.0])), m.elastic(np.array([1.0, 0.0]))
    (2.0, 0.5)
    >>> m.force(np.array([1.0, 2.0])), m.linear
    (array([1., 2.]), True)
    """

    mass: sp.spmatrix
    damping: sp.spmatrix
    stiffness: sp.spmatrix
    #: the forces are linear in the state, f = K d and g = C v: the wall step factorizes its matrix once per Δt
    linear: ClassVar[bool] = True

    def kinetic(self, v: np.ndarray) -> float:
        """½ vᵀ M v."""
        return 0.5 * float(v @ (self.mass @ v))

    def elastic(self, d: np.ndarray) -> float:
        """W(d), the stored energy: ½ dᵀ K d."""
        return 0.5 * float(d @ (self.stiffness @ d))

    def force(self, d: np.ndarray) -> np.ndarray:
        """f(d) = ∇W(d), the internal force: K d."""
        return self.stiffness @ d

    def tangent(self, d: np.ndarray) -> sp.spmatrix:
        """K_T(d) = ∂f/∂d: K."""
        return self.stiffness

    def damping_force(self, v: np.ndarray) -> np.ndarray:
        """g(v), the damping force: C v."""
        return self.damping @ v

    def damping_tangent(self, v: np.ndarray) -> sp.spmatrix:
        """C_T(v) = ∂g/∂v: C."""
        return self.damping

    def dissipation(self, v: np.ndarray, dt: float) -> float:
        """Δt vᵀ C v: energy the layer's viscosity takes in one step at the velocity v."""
        return dt * float(v @ (self.damping @ v))

    def scattered(self, P: sp.spmatrix) -> LayerMatrices:
        """The same forms moved to another numbering: P A Pᵀ."""
        return LayerMatrices(
            (P @ self.mass @ P.T).tocsr(),
            (P @ self.damping @ P.T).tocsr(),
            (P @ self.stiffness @ P.T).tocsr(),
        )


@attrs.frozen(eq=False)
class NonlinearForms(LayerMatrices):
    """The forms of a layer whose forces are not linear in its state.  Subclass it (``@attrs.frozen(eq=False)``,
    with the fields your forces need, e.g. the space) and override ``elastic`` (W), ``force`` (∇W) and
    ``tangent`` (∇²W); ``damping_force`` and ``damping_tangent`` too when the damping is nonlinear.

    ``mass`` is the constant mass; ``damping`` and ``stiffness`` are the tangents at rest (d = v = 0): the
    matrix checks, and what a coupler that linearizes the wall at rest uses.  The energy terms are what the
    forces do: the dissipation of a step Δt v·g(v), the stored energy W; the conformance kit checks the
    force against W's gradient and the tangents against the forces' (:mod:`multilayer.testing`).
    """

    linear: ClassVar[bool] = False

    def dissipation(self, v: np.ndarray, dt: float) -> float:
        """Δt v·g(v)."""
        return dt * float(v @ self.damping_force(v))

    def force_size(self, d: np.ndarray) -> np.ndarray | None:
        """Entry by entry, the size of the terms the force f(d) adds up: the scale its round-off is relative to,
        for the residual of a Newton solve (:mod:`multilayer.numerics.newton`).  None by default: the force's
        own magnitude is its scale.  A layer whose force at a DOF sums large contributions that cancel (the
        elements' forces in a prestressed band, at equilibrium under no load) returns their magnitudes summed,
        so that the solve's tolerance is relative to what round-off leaves."""
        return None

    def term_size(self, term: np.ndarray, d: np.ndarray) -> np.ndarray:
        """The size of a force ``term`` of the layer at ``d`` in a residual: |term|, or :meth:`force_size` where
        that is larger."""
        own = self.force_size(d)
        return np.abs(term) if own is None else np.maximum(np.abs(term), own)

    def scattered(self, P: sp.spmatrix) -> LayerMatrices:
        """These forms in another numbering: the matrices P A Pᵀ, the forces P f(Pᵀ d) (:class:`MovedForms`)."""
        P = sp.csr_matrix(P)
        R = P.T.tocsr()
        return MovedForms((P @ self.mass @ R).tocsr(), (P @ self.damping @ R).tocsr(),
                          (P @ self.stiffness @ R).tocsr(), self, P, R)


@attrs.frozen(eq=False)
class MovedForms(NonlinearForms):
    """Nonlinear forms ``own`` moved to another numbering by the prolongation P (a thin layer's line into the
    wall): forces P f(R d), tangents P K_T(R d) R, energy W(R d), with R = Pᵀ."""

    own: NonlinearForms
    P: sp.csr_matrix
    R: sp.csr_matrix

    def elastic(self, d: np.ndarray) -> float:
        return self.own.elastic(self.R @ d)

    def force(self, d: np.ndarray) -> np.ndarray:
        return self.P @ self.own.force(self.R @ d)

    def tangent(self, d: np.ndarray) -> sp.spmatrix:
        return (self.P @ sp.csr_matrix(self.own.tangent(self.R @ d)) @ self.R).tocsr()

    def force_size(self, d: np.ndarray) -> np.ndarray | None:
        own = self.own.force_size(self.R @ d)
        return None if own is None else self.P @ own

    def damping_force(self, v: np.ndarray) -> np.ndarray:
        return self.P @ self.own.damping_force(self.R @ v)

    def damping_tangent(self, v: np.ndarray) -> sp.spmatrix:
        return (self.P @ sp.csr_matrix(self.own.damping_tangent(self.R @ v)) @ self.R).tocsr()

    def dissipation(self, v: np.ndarray, dt: float) -> float:
        return self.own.dissipation(self.R @ v, dt)


class Layer(ABC):
    """A wall layer.  Subclass :class:`ThinLayer` or :class:`ThickLayer`."""

    thin: ClassVar[bool]
    #: whether ``forms`` returns linear forms (:class:`LayerMatrices`); False for :class:`NonlinearForms`.  A
    #: coupler that needs a linear wall refuses the case at validation from it.
    linear: ClassVar[bool] = True

    @abstractmethod
    def forms(self, space: Any) -> LayerMatrices:
        """Mass, damping and stiffness on ``space`` (a nonlinear layer: its :class:`NonlinearForms`)."""

    def essential_dofs(self, space: Any) -> np.ndarray:
        """DOFs held at zero (in the numbering of ``space``)."""
        return np.zeros(0, dtype=np.int64)

    def forms_on_reference(self, space: Any, reference: np.ndarray) -> LayerMatrices:
        """The forms of the layer whose stress-free reference is its mesh moved by the displacement ``reference``
        (``space``'s numbering): the mesh is the wall as imaged under a load, the reference is unloaded
        (``[initial] prestress``, :mod:`multilayer.wall.prestress`).  The forms' energy W(d) is a function of
        the displacement d from the mesh, as ``forms``' is, and the layer at d = ``reference`` is unloaded.

        A finite-strain layer overrides it; by default a layer's reference is its mesh (NotImplementedError).
        """
        raise NotImplementedError(f"{type(self).__name__} has no stress-free reference other than its mesh")

    @classmethod
    def takes_reference(cls) -> bool:
        """Whether the layer overrides :meth:`forms_on_reference` (it can be prestressed)."""
        return cls.forms_on_reference is not Layer.forms_on_reference


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
