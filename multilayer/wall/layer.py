"""The layer contract: what a wall layer gives the core (its matrices and essential DOFs)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

import attrs
import numpy as np
import scipy.sparse as sp

from multilayer.geometry.spaces import BandSpace, LineSpace


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
