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

Crank–Nicolson, BDF2 and TR-BDF2 (:mod:`multilayer.numerics.timescheme`) are checked the same
way for order 2; a two-step scheme starts from the exact solution at t = 0
and t = −Δt; TR-BDF2's step is its two stages, each a step of its own scheme
over its sub-step (:func:`stages`).

Driven by a prescribed flow instead (a ``flow-rate`` inlet, the outlet at
p = 0): the profile of the same shape whose flux ∫₀^R u_z dr is Q̂ cos ωt
has the amplitude Q̂ / (R − tanh(κR)/κ), and the pressure gradient that
drives it is ρλ times that amplitude (λ the symbol); the inlet's multiplier
is the exact mean inlet pressure G L cos ωt at the step's test level.  The
flux is imposed on each new level, so backward Euler's exact periodic
solution is the profile with κ from its symbol and the flux Q̂ itself.
Errors in u as above (relative to Q̂/R √(LR)), in λ relative to |G| L.
Measured (Q̂ = 1 cm²/s):

    space, BE symbol, Δt = T/20, 4 steps, nz = nr = 4, 8, 16, 32
      P2/P1   u 6.56e-3  9.16e-4  1.17e-4  1.47e-5   orders 2.84 2.97 2.99
              λ 3.37e-4  1.54e-5  8.39e-7  5.05e-8   orders 4.45 4.20 4.06
      P1b/P1  u 3.05e-2  9.92e-3  2.64e-3  6.68e-4   orders 1.62 1.91 1.98
              λ 1.47e-2  3.62e-3  8.97e-4  2.24e-4   orders 2.02 2.01 2.00
    time, P2 nz = 4, to T/2, Δt = T/10 … T/80 (nr = 16; T/20 … T/80 and nr = 32 for CN, BDF2)
      BE      u 2.93e-2  1.57e-2  8.16e-3  4.16e-3   orders 0.90 0.95 0.97
              λ 2.86e-1  1.47e-1  7.41e-2  3.71e-2   orders 0.96 0.99 1.00
      CN      u          1.17e-3  2.93e-4  7.43e-5   orders 2.00 1.98
              λ          1.72e-3  3.46e-4  7.59e-5   orders 2.31 2.19
      BDF2    u          4.23e-3  1.12e-3  2.88e-4   orders 1.91 1.97
              λ          8.80e-3  1.32e-3  2.16e-4   orders 2.74 2.61
      TR-BDF2 u          5.77e-4  1.44e-4  3.78e-5   orders 2.01 1.92
              λ          8.97e-4  1.37e-4  2.31e-5   orders 2.71 2.56

(Averaging Q over each step's window instead, as a pressure is, keeps the
velocity orders but leaves Crank–Nicolson's undamped mode in the level
fluxes: CN's u errors 14× larger (1.68e-2 at T/20) and its λ first order,
4.85e-2, 2.38e-2, 1.18e-2.)
"""

import numpy as np
import pytest
from fluid_steps import given, setup_fluid

from multilayer.fluid.contract import Domain
from multilayer.functions.loads import SinePressure
from multilayer.numerics.timescheme import named
from multilayer_plugins.channel import NavierStokes, Stokes
from multilayer_plugins.channel.probes import l2_error
from multilayer_plugins.flow_rate import FlowRate

L, R, MU, RHO = 1.0, 0.5, 0.035, 1.0
PERIOD = 1.0
OMEGA = 2 * np.pi / PERIOD


def kappa_of(lam):
    """κ = √(ρλ/μ) for the symbol λ (iω: continuous, BE symbol: discrete)."""
    return np.sqrt(RHO * lam / MU)


def profile(amplitude, lam):
    """u(t) = Re{amplitude (1 − cosh κr / cosh κR) e^{iωt}} as a function of (z, r)."""
    kappa = kappa_of(lam)

    def at(t):
        def u(z, r):
            U = amplitude * (1 - np.cosh(kappa * r) / np.cosh(kappa * R)) * np.exp(1j * OMEGA * t)
            return np.real(U), 0 * r

        return u

    return at


def womersley(G, lam):
    """u(t) driven by the pressure gradient G cos ωt averaged over each step."""
    return profile(G / (1j * OMEGA * RHO), lam)


def flux_amplitude(Q, lam):
    """The amplitude of the profile whose flux is Q: ∫₀^R (1 − cosh κr / cosh κR) dr = R − tanh(κR)/κ."""
    kappa = kappa_of(lam)
    return Q / (R - np.tanh(kappa * R) / kappa)


def mean_pressure_drop(G, t, dt):
    """(1/Δt) ∫ G L cos(ωs) ds over [t, t + Δt]."""
    return G * L * (np.sin(OMEGA * (t + dt)) - np.sin(OMEGA * t)) / (OMEGA * dt)


def stages(fluid, history, S, t, dt, loads=None):
    """One step of ``S`` from ``history`` (newest first) at t: its stages one after the other, each a step of the
    stage's scheme over its sub-step from the levels before it (``loads(a, b)`` sets the ends' pressures over a
    stage's load window), each closing its A2 identity; the new state and the last stage's identity terms."""
    chain = list(history)
    for stage, t0, t1, step in S.substeps(t, t + dt, dt):
        a, b = stage.load_window(t0, t1)
        if loads is not None:
            loads(a, b)
        solution, energy = fluid.step(chain, Domain.still(fluid.line.ndofs), stage, step, (t0, t1))
        chain.insert(0, solution.state)
        assert abs(energy["a2.residual"]) <= 1e-12 * energy["a2.scale"]
    return solution, energy


def march(fluid, exact, G, dt, steps, scheme):
    """``steps`` steps of the set-up ``fluid`` under the mean pressure drop of G L cos ωt, each closing its A2
    identity, from the exact solution at t = 0 and, for a two-step scheme, at t = −Δt (no start-up error):
    the last state and its time."""
    S = named(scheme)
    history, t = [fluid.initial_state(exact(0.0)), fluid.initial_state(exact(-dt))], 0.0

    def loads(a, b):
        given(fluid, p_in=mean_pressure_drop(G, a, b - a), p_out=0.0)

    for _ in range(steps):
        solution, _ = stages(fluid, history, S, t, dt, loads)
        history, t = [solution.state, history[0]], t + dt
    return history[0], t


def run(cls, order, nz, nr, dt, steps, discrete_reference, G=10.0, scheme="backward-euler"):
    lam = (1 - np.exp(-1j * OMEGA * dt)) / dt if discrete_reference else 1j * OMEGA
    exact = womersley(G, lam)
    fluid = cls(RHO, MU)
    setup_fluid(fluid, L, R, nz=nz, nr=nr, order=order, wall="rigid")
    state, t = march(fluid, exact, G, dt, steps, scheme)
    scale = G / (OMEGA * RHO) * np.sqrt(L * R)
    return fluid, state, l2_error(fluid.channel, state.u, np.zeros(fluid.line.ndofs), exact(t)) / scale


def run_flux(order, nz, nr, dt, steps, discrete_reference, Q=1.0, scheme="backward-euler"):
    """Womersley flow driven by the inflow Q cos ωt (a flow-rate inlet), p = 0 at the outlet.

    Returns the relative L² error of u at the end and that of the inlet's multiplier λ in the last step.
    """
    lam = (1 - np.exp(-1j * OMEGA * dt)) / dt if discrete_reference else 1j * OMEGA
    amplitude = flux_amplitude(Q, lam)
    G = RHO * lam * amplitude  # −∂p/∂z: ρλU − μU'' = G
    exact = profile(amplitude, lam)
    S = named(scheme)
    fluid = Stokes(RHO, MU)
    inflow = SinePressure(amplitude=Q, frequency=1.0 / PERIOD, phase=np.pi / 2)  # Q cos ωt
    setup_fluid(fluid, L, R, nz=nz, nr=nr, order=order, wall="rigid", ends={"inlet": FlowRate(inflow)})
    history, t = [fluid.initial_state(exact(0.0)), fluid.initial_state(exact(-dt))], 0.0
    for _ in range(steps):
        solution, energy = stages(fluid, history, S, t, dt)
        history, t = [solution.state, history[0]], t + dt
        # the new level carries the prescribed flow exactly
        assert fluid.flow_rate(solution.state, None, 0.0) == pytest.approx(Q * np.cos(OMEGA * t), abs=1e-12 * Q)
    last, start, end, step = S.substeps(t - dt, t, dt)[-1]
    inlet = np.real(G * L * np.exp(1j * OMEGA * (start + last.theta * step)))  # at the (last stage's) test level
    scale = Q / R * np.sqrt(L * R)
    velocity = l2_error(fluid.channel, history[0].u, np.zeros(fluid.line.ndofs), exact(t)) / scale
    return velocity, abs(energy["end.inlet.p"] - inlet) / (abs(G) * L)


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


@pytest.mark.parametrize("scheme", ["crank-nicolson", "bdf2", "tr-bdf2"])
def test_time_convergence_of_the_second_order_schemes(scheme):
    """Crank–Nicolson (pressure at the midpoint), BDF2 and TR-BDF2 against the continuous profile.

    Measured (P2, nz = 4, nr = 32, to T/2, Δt = T/20, T/40, T/80):
    CN 1.11e-3, 2.78e-4, 7.16e-5 (orders 2.00, 1.96); BDF2 7.42e-3, 2.07e-3, 5.83e-4
    (orders 1.85, 1.83; 1.90, 1.84 at T/160, T/320: BDF2's larger constant,
    and a space-error floor of ~5e-6); TR-BDF2 1.06e-3, 2.42e-4, 6.03e-5 (orders 2.13, 2.01;
    2.26e-5 at T/160, where the floor shows).  Backward Euler: order 1 (above).
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


@pytest.mark.parametrize("order, expected", [(2, 3.0), (1, 2.0)])
def test_flux_driven_space_convergence_at_the_element_order(order, expected):
    """u at the element's order (P2 2.97, 2.99; P1b 1.91, 1.98), λ at least (P2 4.20, 4.06; P1b 2.01, 2.00)."""
    velocity, inlet = zip(*[run_flux(order, n, n, PERIOD / 20, 4, True) for n in (8, 16, 32)])
    assert np.all(np.abs(orders(velocity) - expected) < 0.1), orders(velocity)
    assert np.all(orders(inlet) > expected - 0.1), orders(inlet)


def test_flux_driven_time_convergence_is_first_order():
    """Backward Euler: u 0.95, 0.97 and λ 0.99, 1.00 (from T/20)."""
    velocity, inlet = zip(*[run_flux(2, 4, 16, PERIOD / n, n // 2, False) for n in (20, 40, 80)])
    assert velocity[0] < 2e-2 and inlet[0] < 0.2
    assert np.all(np.abs(orders(velocity) - 1.0) < 0.06), orders(velocity)
    assert np.all(np.abs(orders(inlet) - 1.0) < 0.06), orders(inlet)


@pytest.mark.parametrize("scheme", ["crank-nicolson", "bdf2", "tr-bdf2"])
def test_flux_driven_time_convergence_of_the_second_order_schemes(scheme):
    """u: CN 2.00, 1.98, BDF2 1.91, 1.97, TR-BDF2 2.01, 1.92; λ: CN 2.31, 2.19, BDF2 2.74, 2.61, TR-BDF2 2.71, 2.56
    (T/20 … T/80, nr = 32)."""
    velocity, inlet = zip(*[run_flux(2, 4, 32, PERIOD / n, n // 2, False, scheme=scheme) for n in (20, 40, 80)])
    assert np.all(orders(velocity) > 1.8), orders(velocity)
    assert np.all(orders(inlet) > 1.8), orders(inlet)
