"""The fluid step's energy identity: its quadrature, and that it is not vacuous."""

import numpy as np
import pytest
from fluid_steps import BE, given, setup_fluid

from multilayer.fluid.contract import Domain, Interface
from multilayer.numerics.timescheme import stage_schemes
from multilayer_plugins.channel import NavierStokes, forms
from multilayer_plugins.channel.ledger import end_fluxes, fluid_kinetic
from multilayer_plugins.channel.step import Solution


def moving_step(seed=0, scheme=BE):
    """A Navier–Stokes step of ``scheme`` on a deformed, moving channel with a Robin wall, from a random flow."""
    fluid = NavierStokes(density=1.0, viscosity=0.035)
    step = setup_fluid(fluid, 2.0, 0.5, nz=8, nr=3)
    rng = np.random.default_rng(seed)
    n = fluid.line.ndofs
    z = fluid.line.z
    eta = 0.02 * np.sin(np.pi * z / 2.0)
    v = 0.5 * np.sin(np.pi * z / 2.0)
    state = fluid.initial_state(lambda zz, rr: (1.0 - 4 * rr**2 + 0.1 * np.sin(3 * zz), 0.05 * rr * np.cos(zz)), eta)
    dt = 1e-3
    M = 0.11 * np.eye(n)
    interface = Interface(M / dt, M @ v / dt)
    domain = Domain(eta + 0.5 * dt * v, v)
    given(fluid, p_in=50.0, p_out=10.0)
    system = fluid.system([state], domain, scheme, dt, (0.0, dt), interface=interface)
    return fluid, step, system, eta, eta + dt * v, rng


def test_quadrature_matches_scikit_fem():
    fluid, step, system, eta_old, eta_new, rng = moving_step()
    ch, fields = step.channel, system.fields
    u = rng.standard_normal(ch.nu)
    assert step._quadrature.kinetic(fields.J, step._quadrature.values(u)) == pytest.approx(fluid_kinetic(ch, 1.0, fields.J, u), rel=1e-13)
    strain = float(forms.strain_squared.assemble(ch.velocity, u=ch.velocity.interpolate(u), **fields.forms_kwargs()))
    assert step._quadrature.strain_squared(u, fields) == pytest.approx(strain, rel=1e-13)
    q_in, q_out = end_fluxes(ch, fields, u)
    assert fields.J_in * float(step.ends.loads["inlet"] @ u) == pytest.approx(q_in, rel=1e-12)
    assert -fields.J_out * float(step.ends.loads["outlet"] @ u) == pytest.approx(q_out, rel=1e-12)


@pytest.mark.parametrize("scheme", sorted(stage_schemes()))  # every stage of every registered scheme
def test_fluid_identity_closes_and_detects_a_wrong_term_or_a_wrong_solve(scheme):
    fluid, step, system, eta_old, eta_new, rng = moving_step(scheme=stage_schemes()[scheme])
    solution = fluid.solve(system)
    terms = fluid.identity(system, solution, eta_old, eta_new)
    assert abs(terms["a2.residual"]) <= 1e-12 * terms["a2.scale"]
    # a term dropped: the viscous dissipation (measured 9.2e-4 – 1.1e-3 of the scale over the schemes)
    assert abs(terms["a2.residual"] - terms["dissipation.viscous.fluid"]) > 5e-4 * terms["a2.scale"]
    # a solve off by 1e-6 (relative) in a random direction: the identity sees it, ≫ the 1e-9 the tests allow
    scale = np.linalg.norm(solution.mean) / np.sqrt(solution.mean.size)
    mean = solution.mean + 1e-6 * scale * rng.standard_normal(solution.mean.size)
    mean[system.fixed] = solution.mean[system.fixed]
    wrong = fluid.advance(system, mean)
    off = fluid.identity(system, Solution(wrong.mean, wrong.state), eta_old, eta_new)
    assert abs(off["a2.residual"]) > 1e-8 * off["a2.scale"]
    # the inlet's work dropped
    assert abs(terms["a2.residual"] - terms["work.inlet"]) > 1e-6 * terms["a2.scale"]
