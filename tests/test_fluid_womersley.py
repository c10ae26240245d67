"""Womersley flow in the rigid channel (theory §8): first order in time, element order in space.

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

Crank–Nicolson and BDF2 (:mod:`multilayer.numerics.timescheme`) are checked the same
way for order 2; a two-step scheme starts from the exact solution at t = 0
and t = −Δt.
"""

import numpy as np
import pytest
from fluid_steps import given, setup_fluid

from multilayer.fluid.contract import Domain
from multilayer.numerics.timescheme import SCHEMES
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


def run(cls, order, nz, nr, dt, steps, discrete_reference, G=10.0, scheme="backward-euler"):
    lam = (1 - np.exp(-1j * OMEGA * dt)) / dt if discrete_reference else 1j * OMEGA
    exact = womersley(G, lam)
    S = SCHEMES[scheme]
    fluid = cls(RHO, MU)
    setup_fluid(fluid, L, R, nz=nz, nr=nr, order=order, wall="rigid")
    still = Domain.still(fluid.line.ndofs)
    # the exact solution at t = 0 and, for a two-step scheme, at t = −Δt: no start-up error
    history, t = [fluid.initial_state(exact(0.0)), fluid.initial_state(exact(-dt))], 0.0
    for _ in range(steps):
        a, b = S.load_window(t, t + dt)
        given(fluid, p_in=mean_pressure_drop(G, a, b - a), p_out=0.0)
        solution, energy = fluid.step(history, still, S, dt, (a, b))
        history, t = [solution.state, history[0]], t + dt
        assert abs(energy["a2.residual"]) <= 1e-12 * energy["a2.scale"]
    state = history[0]
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


@pytest.mark.parametrize("scheme", ["crank-nicolson", "bdf2"])
def test_time_convergence_of_the_second_order_schemes(scheme):
    """Crank–Nicolson (pressure at the midpoint) and BDF2 against the continuous profile.

    Measured (P2, nz = 4, nr = 32, to T/2, Δt = T/20, T/40, T/80):
    CN 1.11e-3, 2.78e-4, 7.16e-5 (orders 2.00, 1.96); BDF2 7.42e-3, 2.07e-3, 5.83e-4
    (orders 1.85, 1.83; 1.90, 1.84 at T/160, T/320: BDF2's larger constant,
    and a space-error floor of ~5e-6).  Backward Euler: order 1 (above).
    """
    errors = [run(Stokes, 2, 4, 32, PERIOD / n, n // 2, False, scheme=scheme)[2] for n in (20, 40, 80)]
    assert np.all(orders(errors) > 1.8), orders(errors)


def test_stokes_factorizes_once_and_navier_stokes_every_step():
    stokes, _, _ = run(Stokes, 2, 2, 2, PERIOD / 20, 3, False)
    navier, _, _ = run(NavierStokes, 2, 2, 2, PERIOD / 20, 3, False)
    assert stokes.discrete.stats.factorizations == 1
    # the Oseen matrix changes every step: factorized, or solved by GMRES on an earlier factorization
    st = navier.discrete.stats
    assert st.factorizations + st.krylov_solves == 3 and st.factorizations >= 1
    assert stokes.discrete.stats.solves == 3
