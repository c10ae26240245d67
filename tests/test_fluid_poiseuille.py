"""Steady Poiseuille flow in the rigid channel (theory §8), by time-stepping to steady state.

u_z = ΔP (R² − r²)/(2μL), p linear.  Taylor–Hood holds it exactly; MINI
converges at second order in L² (errors 4.83e-2, 1.21e-2, 3.03e-3, 7.61e-4
on nr = 2, 4, 8, 16 with nz = 3 nr: orders 2.00, 1.99, 1.99).

Navier–Stokes does *not* have Poiseuille as its solution with the
dynamic-pressure condition p + ρ|u|²/2 = P (``ends = "total-pressure"``): the
profile would make the static pressure at the ends depend on r, while
parallel flow needs ∂_r p = 0.  The weak form keeps −½ρ∫U²[q_z(L) − q_z(0)] dr
although u·∇u = 0 inside: an end effect of relative size ∝ Re (measured
4.41e-3 at Re 0.85, 4.41e-5 at Re 0.0085).  Static-pressure ends with β = 0
(the convective form's do-nothing condition) do have it: the end term
cancels that boundary integral, to the quadrature's error (measured 7.5e-9
at Re 0.85).  With β = 1, the default, the inlet, where the flow comes in,
holds the total pressure and the outlet the static one: the inlet's ½ρU² is
lost from the drive (measured 1.25e-2 at Re 0.85, ∝ Re).
"""

import numpy as np
import pytest
from fluid_steps import fluid_step, setup_fluid

from multilayer_plugins.channel import NavierStokes, Stokes
from multilayer_plugins.channel.probes import l2_error

L, R, MU, RHO = 6.0, 0.5, 0.035, 1.0


def poiseuille(dp):
    return lambda z, r: (dp * (R**2 - r**2) / (2 * MU * L), 0 * r)


def steady(cls, order, nz, nr, dp, steps=12, **params):
    """March with Δt = 1000 s from rest: each step divides the distance to steady state by ~350."""
    fluid = cls(RHO, MU, **params)
    setup_fluid(fluid, L, R, nz=nz, nr=nr, order=order, wall="rigid")
    state = fluid.initial_state()
    for _ in range(steps):
        state, _ = fluid_step(fluid, state, 1e3, p_in=dp, p_out=0.0)
    return fluid, state


def relative_error(fluid, state, dp):
    eta = np.zeros(fluid.line.ndofs)
    exact = poiseuille(dp)
    return l2_error(fluid.channel, state.u, eta, exact) / l2_error(fluid.channel, 0 * state.u, eta, exact)


def test_taylor_hood_reproduces_poiseuille():
    dp = 10.0
    fluid, state = steady(Stokes, 2, nz=4, nr=4, dp=dp)
    assert relative_error(fluid, state, dp) < 1e-12  # measured 1e-15
    z = np.array([0.0, 1.7, 3.0, 6.0])
    p = fluid.pressure(state, None, z, 0.3 * np.ones(4))
    assert np.allclose(p, dp * (1 - z / L), rtol=0, atol=1e-11 * dp)
    q = dp * R**3 / (3 * MU * L)
    for zz in (0.0, 1.3, 6.0):
        assert fluid.flow_rate(state, None, zz) == pytest.approx(q, rel=1e-12)
    assert fluid.discrete.stats.factorizations == 1  # Stokes, rigid wall, fixed Δt


def test_mini_converges_at_second_order():
    dp = 10.0
    errors = [relative_error(*steady(Stokes, 1, nz=3 * nr, nr=nr, dp=dp), dp) for nr in (2, 4, 8)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert errors[0] < 6e-2  # measured 4.83e-2
    assert np.all(orders > 1.9), orders  # measured 2.00, 1.99


@pytest.mark.parametrize("params, bound", [
    ({"ends": "total-pressure"}, 1e-2),  # measured 4.41e-3
    ({}, 2e-2),  # static-pressure, β = 1: measured 1.25e-2
])
def test_navier_stokes_departs_from_poiseuille_by_the_dynamic_pressure_end_effect(params, bound):
    deviations = []
    for dp in (0.1, 0.001):  # Re = ρ U_max R / μ = 0.85 and 0.0085
        fluid, state = steady(NavierStokes, 2, nz=12, nr=4, dp=dp, steps=8, **params)
        deviations.append(relative_error(fluid, state, dp))
    assert bound / 3 < deviations[0] < bound
    assert deviations[0] / deviations[1] == pytest.approx(100.0, rel=0.03)  # ∝ Re: measured 100.1, 98.2


def test_navier_stokes_holds_poiseuille_with_the_do_nothing_end():
    """β = 0: the end term is the convective form's boundary integral, which the skew form lacks."""
    dp = 0.1  # Re 0.85
    fluid, state = steady(NavierStokes, 2, nz=12, nr=4, dp=dp, steps=8, ends="static-pressure", backflow=0.0)
    assert relative_error(fluid, state, dp) < 1e-7  # measured 7.5e-9 (the cells' and facets' quadrature)


def test_poiseuille_in_a_dilated_channel():
    """η = c everywhere (ends included): Poiseuille of radius R + c, through the ALE fields.

    The inlet and outlet loads are integrated over the physical ends
    (J = (R + c)/R); a load on the reference ends would give R/(R + c) of the flux.
    """
    c, dp = 0.1, 10.0
    fluid = Stokes(RHO, MU)
    setup_fluid(fluid, L, R, nz=4, nr=4, order=2, wall="prescribed")
    eta, still = np.full(fluid.line.ndofs, c), np.zeros(fluid.line.ndofs)
    state = fluid.initial_state()
    for _ in range(12):
        state, _ = fluid_step(fluid, state, 1e3, eta, still, p_in=dp, p_out=0.0)
    wide = (R + c) ** 2
    exact = lambda z, r: (dp * (wide - r**2) / (2 * MU * L), 0 * r)  # noqa: E731
    error = l2_error(fluid.channel, state.u, eta, exact) / l2_error(fluid.channel, 0 * state.u, eta, exact)
    assert error < 1e-12
    assert fluid.flow_rate(state, eta, 2.0) == pytest.approx(dp * (R + c) ** 3 / (3 * MU * L), rel=1e-12)
