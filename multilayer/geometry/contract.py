"""The geometry contract: what a scene's geometry decides, and the plugin kind that provides one.

Every field of a scene lives on the meridian plane (z, r): the fluid on the
reference channel (0, L) × (0, R), the wall's bands beyond r = R, thin
layers on lines r = const.  What the plane stands for is the geometry's: a
planar channel of unit depth (``planar``), or a tube (``axisymmetric``),
or anything whose volume element is a weight times dz dr.  The geometry
owns that weight, the **measure**

    ∫_V f dV = ∫∫ f(z, r) weight(r) dz dr,

and so every integral of the scene: the layers' and the fluid's matrices,
energies and work, the lumen's unit load, the flow rate through a section.
The core never assumes one: it hands each field a basis whose quadrature
weights already carry the measure (:meth:`Geometry.weighted`), and a
layer's ``forms(space)`` or a fluid's setup reach the geometry through
their space (``space.geometry``) when a term needs more than the measure
(the hoop terms of a tube).

The weight is c·rᵏ: under the explicit ALE map r = J r̂ (theory §2), the
volume element of the deformed domain is J^{1+k} times the reference one,
so :attr:`Geometry.radial_power` k is what a fluid needs to move its
measure with the wall.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np


class Geometry(ABC):
    """What the meridian plane (z, r) stands for: the measure of every integral of a scene.

    Subclass it, give :meth:`weight`, and register it as a geometry plugin
    (``multilayer_geometries``); a case chooses it with ``[geometry] model``.

    Examples
    --------
    >>> class Deep(Geometry):
    ...     name = "deep"
    ...     def weight(self, r):
    ...         return np.full_like(np.asarray(r, dtype=float), 3.0)
    >>> float(Deep().line_weight(0.5)), Deep().radial_power
    (3.0, 0)
    """

    #: the geometry's name, as ``[geometry] model`` gives it
    name: ClassVar[str] = ""
    #: k in weight(r) = c rᵏ: 0 for a planar measure, 1 for an axisymmetric one
    radial_power: ClassVar[int] = 0
    #: the units of the scene's integrals, for labels: an energy, a flow rate (per unit depth by default)
    integral_units: ClassVar[dict[str, str]] = {"energy": "erg/cm", "flow_rate": "cm²/s"}

    @abstractmethod
    def weight(self, r: Any) -> np.ndarray:
        """The measure's density on the meridian plane at radius ``r`` (cm): dV = weight(r) dz dr.

        Vectorised over ``r``; returns an array of its shape.
        """

    def line_weight(self, radius: float) -> float:
        """The measure of a line r = ``radius``: dA = line_weight · dz (a thin layer's, the lumen's)."""
        return float(np.asarray(self.weight(np.array([float(radius)])))[0])

    def stretch(self, J: Any) -> Any:
        """The volume element's growth J^{1+k} when the ALE map stretches r by J (theory §2)."""
        return J if self.radial_power == 0 else J ** (1 + self.radial_power)

    def stretch_rate(self, J_before: Any, J_after: Any, rate: Any) -> Any:
        """(J_after^{1+k} − J_before^{1+k}) / Δt for J moving at ``rate`` = (J_after − J_before)/Δt.

        The volume element's growth over a step, exact to round-off (the
        factored difference rate·Σᵢ J_afterⁱ J_beforeᵏ⁻ⁱ, no cancellation):
        a fluid's moving-domain term with it leaves no geometric remainder
        in the energy identity (theory §5, §11).  ``rate`` itself for k = 0.

        >>> class Tube(Geometry):
        ...     radial_power = 1
        ...     def weight(self, r):
        ...         return np.asarray(r, dtype=float)
        >>> float(Tube().stretch_rate(1.0, 1.5, 0.5)), float((1.5 ** 2 - 1.0) / 1.0)
        (1.25, 1.25)
        """
        if self.radial_power == 0:
            return rate
        return rate * sum(J_after**i * J_before ** (self.radial_power - i) for i in range(self.radial_power + 1))

    def section(self, radius: Any) -> Any:
        """The section 0 < r < ``radius`` per unit z: ∫₀^radius weight(r) dr = radius·weight(radius)/(1+k).

        The lumen's volume is the integral of its section along z (theory §7, "Volume"):
        R + η per unit depth in a planar channel, π(R + η)² in a tube.

        >>> class Tube(Geometry):
        ...     radial_power = 1
        ...     def weight(self, r):
        ...         return 2.0 * np.pi * np.asarray(r, dtype=float)
        >>> round(float(Tube().section(2.0)) / np.pi, 12)
        4.0
        """
        radius = np.asarray(radius, dtype=float)
        return radius * np.asarray(self.weight(radius), dtype=float) / (1 + self.radial_power)

    def section_change(self, before: Any, after: Any) -> Any:
        """section(after) − section(before) without the cancellation of the difference (theory §7, "Volume").

        weight = c rᵏ makes the section c ρ^{1+k}/(1+k); its difference is
        c/(1+k) (after − before) Σᵢ afterⁱ beforeᵏ⁻ⁱ, as :meth:`stretch_rate` factors J^{1+k}.

        >>> class Tube(Geometry):
        ...     radial_power = 1
        ...     def weight(self, r):
        ...         return np.asarray(r, dtype=float)
        >>> h = 2.0 ** -40  # (1 + h)²/2 − 1/2 = h + h²/2, exact here where the subtraction keeps about 4 digits
        >>> float(Tube().section_change(1.0, 1.0 + h)) == h + h * h / 2
        True
        """
        before, after = np.asarray(before, dtype=float), np.asarray(after, dtype=float)
        return self.line_weight(1.0) / (1 + self.radial_power) * self.stretch_rate(before, after, after - before)

    def weighted(self, basis: Any, radius: float | None = None) -> Any:
        """``basis`` with its quadrature weights ``dx`` multiplied by the measure, in place; returned.

        A cell or facet basis of the (z, r) plane takes the weight at each
        quadrature point's r; a basis of a line (1D, in z) takes the line's
        weight at ``radius``.  Every form assembled on the result, and every
        quadrature taken with its ``dx``, integrates in this geometry.
        """
        x = np.asarray(basis.global_coordinates())
        if x.shape[0] == 1:
            if radius is None:
                raise ValueError("a line basis needs the radius of its line")
            w = self.line_weight(radius)
        else:
            w = np.asarray(self.weight(x[1]), dtype=float)
        basis.dx = basis.dx * w
        return basis

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"
