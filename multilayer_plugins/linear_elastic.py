"""``linear-elastic``: a thick wall band of 2D linear elasticity (theory §1).

ρ₂ d_tt = ∇·S,  S = μ_s(∇d + ∇dᵀ) + λ_s(∇·d)I, on a radial band of thickness H.
Forms of A1: mass ρ₂ ∫ V·Ψ and a_S(d, Ψ) = ∫ 2μ_s D(d):D(Ψ) + λ_s (∇·d)(∇·Ψ).

In a tube (a geometry of radial power k = 1, theory §11) the strain has the
hoop entry ε_θθ = d_r/r, in ε and in tr ε = ∇·d + d_r/r: ``a_S`` gains the form
``hoop`` (each of the k hoop directions its own d_r/r), read from the
space's geometry.  Every integral is in the space's measure.
"""

from __future__ import annotations

import attrs
import numpy as np
import scipy.sparse as sp
import skfem
from skfem.helpers import ddot, div, dot, sym_grad

from multilayer.geometry.spaces import BandSpace
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import LayerPlugin, Param
from multilayer.wall.layer import LayerMatrices, ThickLayer


@skfem.BilinearForm
def mass(u, v, w):
    """∫ ρ₂ u·v"""
    return w.density * dot(u, v)


@skfem.BilinearForm
def a_S(u, v, w):
    """∫ 2μ_s D(u):D(v) + λ_s (∇·u)(∇·v)"""
    return 2.0 * w.mu * ddot(sym_grad(u), sym_grad(v)) + w.lam * div(u) * div(v)


@skfem.BilinearForm
def hoop(u, v, w):
    """a_S's hoop part: ∫ 2μ_s k (u_r/r)(v_r/r) + λ_s [(∇·u + k u_r/r)(∇·v + k v_r/r) − (∇·u)(∇·v)]."""
    eu, ev = w.k * u[1] / w.x[1], w.k * v[1] / w.x[1]
    return 2.0 * w.mu / w.k * eu * ev + w.lam * (eu * div(v) + div(u) * ev + eu * ev)


@attrs.frozen
class LinearElasticBand(ThickLayer):
    """A thick band.  Units: density g/cm³, thickness cm, Lamé constants dyn/cm².

    ``ends``: ``"clamped"`` (d = 0 at z = 0, L) or ``"sliding"`` (d_z = 0 there);
    ``faces``: ``"free"`` or ``"sliding"`` (d_r = 0 on the band's inner and outer faces);
    ``outer``: ``"free"`` or ``"clamped"`` (d = 0 on the outer face r = R + H: a band tethered to
    stiff surroundings, as in the static solution of theory §1).
    """

    density: float
    thickness: float
    mu: float
    lam: float
    ends: str = "clamped"
    faces: str = "free"
    outer: str = "free"

    @classmethod
    def from_young_poisson(cls, density: float, thickness: float, young: float, poisson: float,
                           **kw) -> LinearElasticBand:
        mu = young / (2.0 * (1.0 + poisson))
        lam = young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson))
        return cls(density=density, thickness=thickness, mu=mu, lam=lam, **kw)

    @property
    def wave_speeds(self) -> tuple[float, float]:
        """(c_p, c_s) = (√((λ+2μ)/ρ), √(μ/ρ)), cm/s."""
        return (np.sqrt((self.lam + 2 * self.mu) / self.density), np.sqrt(self.mu / self.density))

    def forms(self, space: BandSpace) -> LayerMatrices:
        b = space.basis
        M = mass.assemble(b, density=self.density)
        K = a_S.assemble(b, mu=self.mu, lam=self.lam)
        k = space.geometry.radial_power
        if k:
            K = K + hoop.assemble(b, mu=self.mu, lam=self.lam, k=float(k))
        return LayerMatrices(M.tocsr(), sp.csr_matrix(M.shape), K.tocsr())

    def essential_dofs(self, space: BandSpace) -> np.ndarray:
        return band_conditions(space, self.ends, self.faces, self.outer)


def band_conditions(space: BandSpace, ends: str, faces: str, outer: str) -> np.ndarray:
    """The DOFs a band's ``ends``, ``faces`` and ``outer`` conditions (:data:`CONDITIONS`) hold at zero."""
    comp = None if ends == "clamped" else "z"
    fixed = [space.side_dofs("z=0", comp), space.side_dofs("z=L", comp)]
    if faces == "sliding":
        fixed += [space.side_dofs("inner", "r"), space.side_dofs("outer", "r")]
    if outer == "clamped":
        fixed.append(space.side_dofs("outer"))
    return np.unique(np.concatenate(fixed))


def _factory(density, thickness, young=None, poisson=None, lame_mu=None, lame_lambda=None,
             ends="clamped", faces="free", outer="free"):
    by_young = young is not None or poisson is not None
    by_lame = lame_mu is not None or lame_lambda is not None
    if by_young == by_lame:
        raise ValueError("give either young and poisson, or lame_mu and lame_lambda (one pair, not both)")
    if by_young:
        if young is None or poisson is None:
            raise ValueError("young and poisson go together: give both")
        return LinearElasticBand.from_young_poisson(density, thickness, young, poisson, ends=ends, faces=faces,
                                                    outer=outer)
    if lame_mu is None or lame_lambda is None:
        raise ValueError("lame_mu and lame_lambda go together: give both")
    if lame_lambda + lame_mu <= 0:
        raise ValueError("lame_lambda + lame_mu must be > 0 (positive-definite elasticity)")
    return LinearElasticBand(density, thickness, lame_mu, lame_lambda, ends=ends, faces=faces, outer=outer)


#: a band's conditions on its ends and faces (:func:`band_conditions`), shared by the thick layers
CONDITIONS = (
    Param("ends", "", "", "clamped", type=str, choices=("clamped", "sliding"),
          doc="ends z = 0, L: clamped (d = 0) or sliding (d_z = 0)"),
    Param("faces", "", "", "free", type=str, choices=("free", "sliding"),
          doc="inner/outer faces: free (traction) or sliding (d_r = 0)"),
    Param("outer", "", "", "free", type=str, choices=("free", "clamped"),
          doc="outer face r = R + H: free (loaded by the external pressure) or clamped (d = 0)"),
)
PARAMS = (
    Param("density", "ρ₂", "g/cm³", gt=0.0, doc="mass density of the band"),
    Param("thickness", "H", "cm", gt=0.0, doc="radial thickness of the band"),
    Param("young", "E", "dyn/cm²", None, gt=0.0, doc="Young's modulus (with poisson)"),
    Param("poisson", "σ", "1", None, gt=-1.0, lt=0.5, doc="Poisson ratio (with young)"),
    Param("lame_mu", "μ_s", "dyn/cm²", None, gt=0.0, doc="shear modulus (with lame_lambda)"),
    Param("lame_lambda", "λ_s", "dyn/cm²", None, doc="first Lamé constant (with lame_mu)"),
    *CONDITIONS,
)


@hookimpl
def multilayer_layers():
    return [LayerPlugin(name="linear-elastic", factory=_factory, params=PARAMS, thin=False,
                        doc="Thick band of linear elasticity, plane strain or axisymmetric (young/poisson or Lamé constants).",
                        example={"density": 1.1, "thickness": 0.1, "young": 7.5e5, "poisson": 0.45})]
