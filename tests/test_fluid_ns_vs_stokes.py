"""Navier–Stokes against Stokes on a prescribed wall motion: the advection terms and nothing else.

η = a sin(πz/L) sin(2πt/T₀), one period; Re = ρ U R/μ with U = 2a L/(R T₀)
the axial speed the squeeze drives.  The relative L² difference of the two
velocities at t = T₀ is linear in Re for small Re (measured 1.00e-5 at
Re 0.057, 1.00e-4 at Re 0.57) and measurable at Re 286 (4.16e-2): the
Galerkin step (``stabilization = "none"``).  Stabilized (SUPG, the default),
the difference stays linear in Re: 9.44e-6, 9.44e-5 and 3.57e-2, and with
grad-div (``grad_div = 1``) 1.86e-5, 1.85e-4 and 3.16e-2 — their terms
vanish with the advecting velocity (static-pressure ends, the default; with
total-pressure ends, whose ends carry no convective term, Galerkin's are
8.97e-6, 8.97e-5 and 4.03e-2).
"""

from functools import partial

import numpy as np
import pytest
from fluid_steps import fluid_step, setup_fluid

from multilayer_plugins.channel import NavierStokes, Stokes, wall_motion
from multilayer_plugins.channel.probes import l2_error

L, R, MU, RHO, T0 = 2.0, 0.5, 0.035, 1.0, 0.02


def final_velocity(cls, a, steps=20):
    fluid = cls(RHO, MU)
    setup_fluid(fluid, L, R, nz=8, nr=4, order=2, wall="prescribed")
    state, t, dt = fluid.initial_state(), 0.0, T0 / steps

    def law(t, z):
        return a * np.sin(np.pi * z / L) * np.sin(2 * np.pi * t / T0)

    for _ in range(steps):
        eta, _, v_half = wall_motion(fluid.line, law, t, dt)
        state, t = fluid_step(fluid, state, dt, eta, v_half)[0], t + dt
    return fluid, state.u


def difference(a, kind=partial(NavierStokes, stabilization="none")):
    fluid, u_ns = final_velocity(kind, a)
    _, u_s = final_velocity(Stokes, a)
    eta, zero = np.zeros(fluid.line.ndofs), lambda z, r: (0 * r, 0 * r)
    return l2_error(fluid.channel, u_ns - u_s, eta, zero) / l2_error(fluid.channel, u_s, eta, zero)


def reynolds(a):
    return RHO * (2 * a * L / (R * T0)) * R / MU


def test_agree_at_tiny_reynolds_and_differ_at_moderate():
    small, smaller, moderate = difference(1e-4), difference(1e-5), difference(0.05)
    assert reynolds(1e-4) < 1 and reynolds(0.05) > 200
    assert small < 1.5e-4  # measured 1.00e-4
    assert small / smaller == pytest.approx(10.0, rel=1e-2)  # ∝ Re
    assert moderate > 2e-2  # measured 4.16e-2


@pytest.mark.parametrize("grad_div, measured", [(0.0, 9.44e-5), (1.0, 1.85e-4)])
def test_the_stabilized_step_departs_from_stokes_in_proportion_to_re(grad_div, measured):
    kind = partial(NavierStokes, stabilization="supg", grad_div=grad_div)
    small, smaller, moderate = (difference(a, kind=kind) for a in (1e-4, 1e-5, 0.05))
    assert small < 1.5 * measured
    assert small / smaller == pytest.approx(10.0, rel=1e-2)  # ∝ Re
    assert moderate > 2e-2  # measured 3.57e-2, 3.16e-2
