"""A thick band in a tube (theory §11): Lamé's thick cylinder under internal pressure, static.

Plane strain (ends sliding: d_z = 0 at z = 0, L, so d_z = 0 everywhere),
inner radius a, outer b = a + H, inner pressure p_i, outer face free:

    d_r = (1 + ν) p_i a² / (E (b² − a²)) · ((1 − 2ν) r + b²/r),   d_z = 0.

The band's a_S has the hoop strain ε_θθ = d_r/r in ε and in tr ε; the load is
p_i on the inner face, ∫ Ψ_r 2πa dz.  d_r is not a polynomial, so the error
is the element's: relative L² errors (over the tube) on square cells,
nr = 2, 4, 8, 16 across a = 0.5, H = 0.5 and nz = 2nr along L = 1, ν = 0.3:

    P2   1.35e-3  1.82e-4  2.33e-5  2.92e-6   orders 2.89 2.97 2.99
    P1   1.81e-2  5.53e-3  1.48e-3  3.81e-4   orders 1.71 1.90 1.96

(At ν = 0.45, the bundled band's: P2 2.87e-3 … 3.78e-6, orders 3.19 3.23
3.15; P1 8.45e-2 … 1.98e-3, orders 1.62 1.85 1.95 — P1's mild locking.
Stretched cells, nz = 2, are far worse: P2 orders 2.75 2.44 2.16.)

Without the hoop terms (the planar band) a uniform pressure would only
translate the band: its stiffness has no radial term (the planar channel's
thick wall), which the test checks too.
"""

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from multilayer.wall.stack import Stack, WallSpace
from multilayer_plugins.axisymmetric import Axisymmetric
from multilayer_plugins.linear_elastic import LinearElasticBand
from multilayer_plugins.planar import Planar

A, H, L = 0.5, 0.5, 1.0
E, NU, P_I = 1e6, 0.3, 1e3
BAND = LinearElasticBand.from_young_poisson(1.1, H, E, NU, ends="sliding")


def lame(r):
    b = A + H
    return (1 + NU) * P_I * A**2 / (E * (b**2 - A**2)) * ((1 - 2 * NU) * r + b**2 / r)


def static(geometry, order, nr):
    space = WallSpace.build([BAND], geometry, L, A, 2 * nr, order, [nr])
    stack = Stack.assemble(space)
    load = P_I * space.line_load(0)
    d = np.zeros(space.ndofs)
    free = stack.free
    d[free] = spla.spsolve(stack.stiffness[free][:, free].tocsc(), load[free])
    return space, d


def relative_error(space, d):
    basis = space.basis
    dh = np.asarray(basis.interpolate(d))
    r = np.asarray(basis.global_coordinates()[1])
    error = np.sum(basis.dx * (dh[0] ** 2 + (dh[1] - lame(r)) ** 2))
    return float(np.sqrt(error / np.sum(basis.dx * lame(r) ** 2)))


@pytest.mark.parametrize("order, expected, first", [(2, 3.0, 1.5e-3), (1, 2.0, 2e-2)])
def test_lame_thick_cylinder_at_the_element_order(order, expected, first):
    errors = [relative_error(*static(Axisymmetric(), order, nr)) for nr in (2, 4, 8, 16)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert errors[0] < first  # measured 1.35e-3 (P2), 1.81e-2 (P1)
    assert np.all(orders > expected - 0.35) and abs(orders[-1] - expected) < 0.1, orders


def test_the_planar_band_has_no_hoop_stiffness():
    """A uniform radial translation costs no energy in the planar band, and K d = 0 for it; in a tube it does."""
    for geometry, free_translation in ((Planar(), True), (Axisymmetric(), False)):
        space = WallSpace.build([BAND], geometry, L, A, 4, 2, [2])
        K = Stack.assemble(space).stiffness
        shift = space.interpolate(lambda z, r, t: 0 * z, lambda z, r, t: 1 + 0 * z)
        energy = float(shift @ K @ shift)
        assert (energy < 1e-9 * E) == free_translation
