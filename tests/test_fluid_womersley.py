"""Womersley flow in the rigid channel (SCHEME §6): first order in time, element order in space.

The channel is planar with a symmetry line, so the profile is
u_z = Re{G/(iωρ) [1 − cosh(κ r)/cosh(κ R)] e^{iωt}}, κ = √(iω/ν), driven
by P_in − P_out = G L cos(ωt) (time-averaged over each step, as A2 asks).

Backward Euler has its own exact periodic solution: the same profile with
iω replaced by λ = (1 − e^{−iωΔt})/Δt in κ (the prefactor does not change
because the pressure is averaged over the step).  Comparing with it
isolates the space error; comparing a fine mesh with the continuous
profile isolates the time error.  Runs start from the exact solution at
t = 0, so there is no start-up transient.  Errors are L² over the channel,
relative to G/(ωρ) √(LR).  Measured (ω = 2π s⁻¹, Womersley number 6.7):

    space, Δt = T/20, 4 steps, nz = nr = 4, 8, 16, 32
      P2/P1   2.50e-3  3.08e-4  4.02e-5  5.11e-6   orders 3.02 2.94 2.98
      P1b/P1  4.45e-2  1.11e-2  2.77e-3  6.92e-4   orders 2.00 2.01 2.00
    time, P2 nz = 4, nr = 16, to t = T/2, Δt = T/10 … T/160
              4.37e-2  2.22e-2  1.12e-2  5.65e-3  2.83e-3   orders 0.97 0.98 0.99 1.00
"""

import numpy as np
import pytest

from multilayer_plugins.channel import NavierStokes, Stokes
from multilayer_plugins.channel.probes import l2_error

L, R, MU, RHO = 1.0, 0.5, 0.035, 1.0
PERIOD = 1.0
OMEGA = 2 * np.pi / PERIOD


def womersley(G, lam):
    """u(t) as a function of (z, r), for the symbol λ (iω: continuous, BE symbol: discrete)."""
    kappa = np.sqrt(RHO * lam / MU)

    def at(t):
        def u(z, r):
            U = G / (1j * OMEGA * RHO) * (1 - np.cosh(kappa * r) / np.cosh(kappa * R)) * np.exp(1j * OMEGA * t)
            return np.real(U), 0 * r

        return u

    return at


def mean_pressure_drop(G, t, dt):
    """(1/Δt) ∫ G L cos(ωs) ds over [t, t + Δt]."""
    return G * L * (np.sin(OMEGA * (t + dt)) - np.sin(OMEGA * t)) / (OMEGA * dt)


def run(cls, order, nz, nr, dt, steps, discrete_reference, G=10.0):
    lam = (1 - np.exp(-1j * OMEGA * dt)) / dt if discrete_reference else 1j * OMEGA
    exact = womersley(G, lam)
    fluid = cls(RHO, MU)
    fluid.setup(L, R, nz=nz, nr=nr, order=order, dt=dt, wall="rigid")
    state, t = fluid.initial_state(exact(0.0)), 0.0
    for _ in range(steps):
        result = fluid.step(state, p_in=mean_pressure_drop(G, t, dt), p_out=0.0)
        state, t = result.state, t + dt
        assert abs(result.energy["a2.residual"]) <= 1e-12 * result.energy["a2.scale"]
    scale = G / (OMEGA * RHO) * np.sqrt(L * R)
    return fluid, state, l2_error(fluid.channel, state.u, np.zeros(fluid.line.ndofs), exact(t)) / scale


def orders(errors):
    e = np.array(errors)
    return np.log2(e[:-1] / e[1:])


@pytest.mark.parametrize("order, expected, first", [(2, 3.0, 3e-3), (1, 2.0, 5e-2)])
def test_space_convergence_at_the_element_order(order, expected, first):
    errors = [run(Stokes, order, n, n, PERIOD / 20, 4, True)[2] for n in (4, 8, 16)]
    assert errors[0] < first
    assert np.all(np.abs(orders(errors) - expected) < 0.15), orders(errors)


def test_time_convergence_is_first_order():
    errors = [run(Stokes, 2, 4, 16, PERIOD / n, n // 2, False)[2] for n in (10, 20, 40, 80)]
    assert errors[0] < 5e-2
    assert np.all(np.abs(orders(errors) - 1.0) < 0.05), orders(errors)


def test_stokes_factorizes_once_and_navier_stokes_every_step():
    stokes, _, _ = run(Stokes, 2, 2, 2, PERIOD / 20, 3, False)
    navier, _, _ = run(NavierStokes, 2, 2, 2, PERIOD / 20, 3, False)
    assert stokes.discrete.stats.factorizations == 1
    assert navier.discrete.stats.factorizations == 3
    assert stokes.discrete.stats.solves == navier.discrete.stats.solves == 3
