"""The fluid in a tube (theory §11): Hagen–Poiseuille and Womersley flow in a rigid pipe.

Hagen–Poiseuille: u_z = ΔP (R² − r²)/(4μL), p linear, and through every
section Q = π ΔP R⁴/(8μL) — the measure is 2πr dr dz with its 2π, so the
flow rate is the pipe's in cm³/s.  Taylor–Hood holds it to round-off
(measured 4e-15 in u, 4e-15 in Q, 3e-14 in p); MINI converges at second
order (relative L² errors 4.47e-2, 1.18e-2, 2.98e-3, 7.49e-4 on nr = 2, 4,
8, 16 with nz = 3 nr: orders 1.93, 1.98, 1.99).

Womersley: for −∂_z p = G e^{iωt} the pipe's profile is
u_z = Re{G/(iωρ) [1 − J0(iκr)/J0(iκR)] e^{iωt}}, κ = √(iωρ/μ) (J0(iκr) is the
J0(i^{3/2} α r/R) of the literature, α = R√(ωρ/μ)), computed with
scipy.special.jv at complex arguments.  As in the planar channel
(tests/test_fluid_womersley.py), backward Euler has its own exact periodic
solution — κ with iω replaced by the symbol λ = (1 − e^{−iωΔt})/Δt — which
isolates the space error, and a fine mesh against the continuous profile
isolates the time error.  Errors are L² over the pipe, relative to
G/(ωρ) √(πR²L).  Measured (ω = 2π s⁻¹, α = 6.7):

    space, Δt = T/20, 4 steps, nz = nr = 4, 8, 16, 32
      P2/P1   2.43e-3  3.54e-4  4.89e-5  6.29e-6   orders 2.78 2.86 2.96
      P1b/P1  4.98e-2  1.24e-2  3.09e-3  7.71e-4   orders 2.01 2.01 2.00
    time, P2 nz = 4, nr = 16 (32 for CN, BDF2), to t = T/2
      BE    Δt = T/10 … T/80   6.14e-2  3.13e-2  1.58e-2  7.96e-3   orders 0.97 0.98 0.99
      CN    Δt = T/20 … T/80   1.62e-3  4.05e-4  1.04e-4            orders 2.00 1.97
      BDF2  Δt = T/40 … T/160  3.12e-3  8.70e-4  2.30e-4            orders 1.84 1.92

(P2's order reaches 3 from below: the weight r makes the axis cells count
less, and the first meshes are pre-asymptotic there.)
"""

import numpy as np
import pytest
import scipy.sparse as sp
from fluid_steps import fluid_step, setup_fluid
from scipy.special import jv
from skfem import asm
from test_fluid_womersley import (
    MU,
    OMEGA,
    PERIOD,
    RHO,
    L,
    R,
    march,
    orders,
)

from multilayer.numerics.assembly.batched import BatchedForm
from multilayer_plugins.axisymmetric import Axisymmetric
from multilayer_plugins.channel import Stokes, forms
from multilayer_plugins.channel.ale import ALEFields
from multilayer_plugins.channel.channel import Channel
from multilayer_plugins.channel.probes import l2_error

TUBE = Axisymmetric()
PIPE_LENGTH = 6.0


def steady_pipe(order, nz, nr, dp):
    """Stokes in the rigid pipe marched with Δt = 1000 s from rest to steady state."""
    fluid = Stokes(RHO, MU)
    setup_fluid(fluid, PIPE_LENGTH, R, nz=nz, nr=nr, order=order, wall="rigid", geometry=TUBE)
    state = fluid.initial_state()
    for _ in range(12):
        state, energy = fluid_step(fluid, state, 1e3, p_in=dp, p_out=0.0)
        assert abs(energy["a2.residual"]) <= 1e-12 * energy["a2.scale"]
    exact = lambda z, r: (dp * (R**2 - r**2) / (4 * MU * PIPE_LENGTH), 0 * r)
    eta = np.zeros(fluid.line.ndofs)
    error = l2_error(fluid.channel, state.u, eta, exact) / l2_error(fluid.channel, 0 * state.u, eta, exact)
    return fluid, state, error


def test_taylor_hood_reproduces_hagen_poiseuille_and_its_flow_rate():
    dp = 10.0
    fluid, state, error = steady_pipe(2, 4, 4, dp)
    assert error < 1e-12  # measured 4e-15
    z = np.array([0.0, 1.7, 3.0, 6.0])
    assert np.allclose(fluid.pressure(state, None, z, 0.3 * np.ones(4)), dp * (1 - z / PIPE_LENGTH),
                       rtol=0, atol=1e-11 * dp)
    q = np.pi * dp * R**4 / (8 * MU * PIPE_LENGTH)  # cm³/s: the measure keeps its 2π
    for zz in (0.0, 1.3, 6.0):
        assert fluid.flow_rate(state, None, zz) == pytest.approx(q, rel=1e-12)


def test_mini_converges_to_hagen_poiseuille_at_second_order():
    errors = [steady_pipe(1, 3 * nr, nr, 10.0)[2] for nr in (2, 4, 8)]
    assert errors[0] < 5e-2  # measured 4.47e-2
    assert np.all(orders(errors) > 1.9), orders(errors)  # measured 1.93, 1.98


def womersley_pipe(G, lam):
    """u(t) in the pipe driven by G e^{iωt} averaged over each step, κ² = ρλ/μ (λ = iω: continuous)."""
    kappa = np.sqrt(RHO * lam / MU)

    def at(t):
        def u(z, r):
            U = G / (1j * OMEGA * RHO) * (1 - jv(0, 1j * kappa * r) / jv(0, 1j * kappa * R)) * np.exp(1j * OMEGA * t)
            return np.real(U), 0 * r

        return u

    return at


def run(order, nz, nr, dt, steps, discrete_reference, G=10.0, scheme="backward-euler"):
    lam = (1 - np.exp(-1j * OMEGA * dt)) / dt if discrete_reference else 1j * OMEGA
    exact = womersley_pipe(G, lam)
    fluid = Stokes(RHO, MU)
    setup_fluid(fluid, L, R, nz=nz, nr=nr, order=order, wall="rigid", geometry=TUBE)
    state, t = march(fluid, exact, G, dt, steps, scheme)
    scale = G / (OMEGA * RHO) * np.sqrt(np.pi * R**2 * L)
    return l2_error(fluid.channel, state.u, np.zeros(fluid.line.ndofs), exact(t)) / scale


@pytest.mark.parametrize("order, expected, first", [(2, 3.0, 3e-3), (1, 2.0, 6e-2)])
def test_womersley_space_convergence_at_the_element_order(order, expected, first):
    errors = [run(order, n, n, PERIOD / 20, 4, True) for n in (4, 8, 16)]
    assert errors[0] < first  # measured 2.43e-3 (P2), 4.98e-2 (P1b)
    assert np.all(np.abs(orders(errors) - expected) < 0.25), orders(errors)  # P2 2.78, 2.86; P1b 2.01, 2.01


def test_womersley_time_convergence_is_first_order_for_backward_euler():
    errors = [run(2, 4, 16, PERIOD / n, n // 2, False) for n in (10, 20, 40, 80)]
    assert errors[0] < 7e-2  # measured 6.14e-2
    assert np.all(np.abs(orders(errors) - 1.0) < 0.05), orders(errors)


@pytest.mark.parametrize("scheme, steps", [("crank-nicolson", (20, 40, 80)), ("bdf2", (40, 80, 160))])
def test_womersley_time_convergence_of_the_second_order_schemes(scheme, steps):
    errors = [run(2, 4, 32, PERIOD / n, n // 2, False, scheme=scheme) for n in steps]
    assert np.all(orders(errors) > 1.8), orders(errors)  # CN 2.00, 1.97; BDF2 1.84, 1.92


@pytest.mark.parametrize("order", [1, 2])
def test_the_batched_assembly_of_a_tube_equals_scikit_fem(order):
    """Every form the step assembles in a tube, hoop terms included, on a deformed, moving, graded channel."""
    ch = Channel.build(TUBE, 2.0, 0.5, nz=4, nr=3, order=order, grading=1.5)
    z = ch.line.z
    f = ALEFields.at(ch, 0.1 * np.sin(np.pi * z / 2.0) * (1.0 + z), 0.3 * np.sin(np.pi * z), 1e-3, 0.0)
    kw, hoop = f.forms_kwargs(), f.hoop_kwargs()
    cases = [(forms.mass_J, (ch.velocity,), kw), (forms.viscous, (ch.velocity,), kw),
             (forms.hoop_viscous, (ch.velocity,), hoop), (forms.moving_domain, (ch.velocity,), {"dJdt": f.dJdt}),
             (forms.pressure_divergence, (ch.velocity, ch.pressure), kw),
             (forms.hoop_divergence, (ch.velocity, ch.pressure), hoop)]
    for form, bases, w in cases:
        B = asm(form, *bases, **w)
        batched = BatchedForm(*bases, chunk=5)
        A = sp.coo_matrix((batched.data([(1.0, form, w)]), (batched.rows, batched.cols)), shape=B.shape).tocsr()
        assert abs(A - B).max() <= 1e-13 * abs(B).max(), form
