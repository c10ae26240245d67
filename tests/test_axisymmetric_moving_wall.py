"""The fluid in a tube whose wall moves (theory §11): energy identity, mass balance, geometric conservation.

Prescribed motion η = a sin(πz/L) sin(2πt/T₀) as in the planar channel
(tests/test_fluid_moving_wall.py).  In a tube the volume element of the
domain of η is J² r̂ dr̂ dz (J = (R + η)/R), its volume V = ∫ π (R + η)² dz.

- **Energy identity.** The step's identity closes to round-off every step
  (direct solves; measured ≤ 4.3e-15 relative, 4.9e-14 for Crank–Nicolson) with the prescribed wall's work, and in the
  coupled mode with a Robin mass, where ηⁿ⁺¹ = ηⁿ + Δt v leaves no geometric
  remainder: the moving-domain term carries the exact growth
  (J²ⁿ⁺¹ − J²ⁿ)/Δt = (v/R)(Jⁿ + Jⁿ⁺¹) of the volume element.
- **Geometric conservation.** That growth, integrated, is the change of the
  domain's volume to round-off: ∫ ∂_t(J²) 2πr̂ dr̂ dz = (Vⁿ⁺¹ − Vⁿ)/Δt.
- **Mass balance.** The divergence row is integrated exactly (degree-7
  quadrature), so Q_in − Q_out = ∫ 2π (R + η_m) v dz, the flux through the wall
  of the step's domain η_m, to round-off.  With the old domain η_m = ηⁿ
  (backward Euler) that differs from the change of volume by exactly
  Δt ∫ π v² dz: the explicit geometry's first-order defect in a tube (none in
  the planar channel, whose volume is linear in η).  On the midpoint domain
  (Crank–Nicolson) the two agree to round-off.
- **Force on the wall.** A fluid at rest at pressure p₀ in a deformed tube
  pushes on the wall with p₀ ∫ ψ 2π(R + η) dz: per unit reference area
  2πR dz, the deformed surface's factor (R + η)/R (theory §11), to round-off.
"""

import attrs
import numpy as np
import pytest
import skfem
from fluid_steps import BE, fluid_step, given, setup_fluid
from test_fluid_moving_wall import MU, RHO, T0, L, R, eta_law

from multilayer.fluid.contract import Domain
from multilayer.numerics.linsolve import Reuse
from multilayer.numerics.timescheme import named
from multilayer_plugins.axisymmetric import Axisymmetric
from multilayer_plugins.channel import NavierStokes, Stokes, wall_motion
from multilayer_plugins.channel.ledger import end_fluxes

TUBE = Axisymmetric()


def line_integral(fluid, f):
    """∫₀ᴸ f(z) dz for a function of z, exactly for the polynomials here (Gauss, degree 12)."""
    basis = skfem.Basis(fluid.line.basis.mesh, fluid.line.basis.elem, intorder=12)
    z = basis.global_coordinates()[0]
    return float(np.sum(basis.dx * f(basis, z)))


def on_line(fluid, x):
    """A line vector's values at the points of a :func:`line_integral`."""
    return lambda basis: np.asarray(basis.interpolate(x))


def wall_flux(fluid, eta, v):
    """∫ 2π (R + η) v dz: the flux through the wall of the domain of η moving at v."""
    return line_integral(fluid, lambda b, z: 2 * np.pi * (R + on_line(fluid, eta)(b)) * on_line(fluid, v)(b))


def squared_speed(fluid, v):
    """∫ π v² dz."""
    return line_integral(fluid, lambda b, z: np.pi * on_line(fluid, v)(b) ** 2)


def volume(fluid, eta):
    """V = ∫ π (R + η)² dz."""
    return line_integral(fluid, lambda b, z: np.pi * (R + on_line(fluid, eta)(b)) ** 2)


def march(cls, order, dt, steps, scheme=BE, nz=8, nr=3):
    fluid = cls(RHO, MU)
    setup_fluid(fluid, L, R, nz=nz, nr=nr, order=order, wall="prescribed", geometry=TUBE, reuse=Reuse("none"))
    state, t, records = fluid.initial_state(), 0.0, []
    for _ in range(steps):
        eta, eta_new, v = wall_motion(fluid.line, eta_law, t, dt)
        domain = Domain(scheme.geometry([eta_new, eta]), v)
        given(fluid, 3.0, 1.0)
        system = fluid.system([state], domain, scheme, dt, (t, t + dt))
        solution = fluid.solve(system)
        energy = fluid.identity(system, solution, eta, eta_new)
        q_in, q_out = end_fluxes(fluid.channel, system.fields, solution.mean[: fluid.channel.nu])
        records.append({"fields": system.fields, "energy": energy, "q": q_in - q_out, "eta": eta,
                        "eta_new": eta_new, "v": v, "domain": domain.eta, "dt": dt})
        state, t = solution.state, t + dt
    return fluid, records


@pytest.mark.parametrize("cls, order", [(NavierStokes, 2), (Stokes, 2), (NavierStokes, 1)])
def test_energy_identity_mass_balance_and_geometric_conservation_every_step(cls, order):
    fluid, records = march(cls, order, T0 / 20, 20)
    dx = fluid.discrete._uu.dx
    for rec in records:
        e, dt = rec["energy"], rec["dt"]
        assert abs(e["a2.residual"]) <= 1e-12 * e["a2.scale"]
        growth = (volume(fluid, rec["eta_new"]) - volume(fluid, rec["eta"])) / dt
        scale = abs(wall_flux(fluid, np.zeros_like(rec["v"]), rec["v"])) + 1e-300
        # geometric conservation: the moving-domain term's growth of the volume element is the volume's
        assert float(np.sum(dx * rec["fields"].dJdt)) == pytest.approx(growth, rel=1e-12, abs=1e-12 * scale)
        # mass balance on the step's domain (ηⁿ), and its defect against the volume: Δt ∫ π v² dz
        assert rec["q"] == pytest.approx(wall_flux(fluid, rec["eta"], rec["v"]), rel=1e-11, abs=1e-11 * scale)
        defect = dt * squared_speed(fluid, rec["v"])
        assert growth - rec["q"] == pytest.approx(defect, rel=1e-9, abs=1e-11 * scale)
    assert any(abs(r["energy"]["work.wall"]) > 1e-3 * r["energy"]["a2.scale"] for r in records)


def test_on_the_midpoint_domain_the_mass_balance_is_the_change_of_volume():
    fluid, records = march(Stokes, 2, T0 / 20, 10, scheme=named("crank-nicolson"))
    for rec in records:
        growth = (volume(fluid, rec["eta_new"]) - volume(fluid, rec["eta"])) / rec["dt"]
        assert rec["q"] == pytest.approx(growth, rel=1e-11, abs=1e-12 * abs(wall_flux(fluid, 0 * rec["v"], rec["v"])))
        e = rec["energy"]
        assert abs(e["a2.residual"]) <= 1e-12 * e["a2.scale"]


def test_energy_identity_with_a_robin_mass_has_no_geometric_remainder_and_sees_the_hoop_dissipation():
    fluid = NavierStokes(RHO, MU)
    setup_fluid(fluid, L, R, nz=6, nr=3, order=2, wall="coupled", geometry=TUBE)
    M = 1.1 * 0.1 * skfem.asm(skfem.BilinearForm(lambda u, v, w: u * v), fluid.line.basis)
    z = fluid.line.z
    eta = 0.02 * np.sin(np.pi * z / L)
    state = fluid.initial_state(lambda zz, rr: (5.0 * (1 - (rr / R) ** 2), 0.3 * rr * np.cos(zz)), eta)
    dt = 2e-3
    for n in range(6):
        v = 3.0 * np.sin(2 * np.pi * z / L) * np.cos(n) + 0.5 * state.v
        v[fluid.line.end_dofs] = 0.0
        new, e = fluid_step(fluid, state, dt, eta, v, robin_mass=M, p_in=20.0 * np.cos(n), p_out=2.0)
        assert abs(e["a2.residual"]) <= 1e-12 * e["a2.scale"]
        assert abs(e["dissipation.geometric.fluid"]) <= 1e-12 * e["a2.scale"]
        state, eta = new, eta + dt * v
    # the hoop part 2μ ∫ J² (u_r/r)² of the dissipation is in the identity: without it, it would not close
    system = fluid.system([state], Domain(eta, v), BE, dt, (0.0, dt))
    fields = system.fields
    quad = fluid.discrete._quadrature
    hoop = quad.strain_squared(state.u, fields) - quad.strain_squared(state.u, attrs.evolve(fields, hoop=None))
    assert hoop > 1e-3 * quad.strain_squared(state.u, fields)


def test_the_force_of_a_fluid_at_rest_carries_the_deformed_surface():
    p0 = 7.0
    fluid = Stokes(RHO, MU)
    setup_fluid(fluid, L, R, nz=8, nr=3, order=2, wall="prescribed", geometry=TUBE)
    eta = 0.05 * np.sin(np.pi * fluid.line.z / L)
    given(fluid, p0, p0)
    system = fluid.system([fluid.initial_state()], Domain(eta, 0 * eta), BE, 1e-3, (0.0, 1e-3))
    solution = fluid.solve(system)
    assert np.abs(solution.state.u).max() < 1e-12 * p0
    phi = skfem.Basis(fluid.line.basis.mesh, fluid.line.basis.elem, intorder=8)
    surface = skfem.asm(skfem.LinearForm(lambda psi, w: 2 * np.pi * (R + w.eta) * psi), phi,
                        eta=phi.interpolate(eta))
    assert np.allclose(fluid.reaction(system, solution.mean), -p0 * surface, rtol=0, atol=1e-12 * p0 * surface.max())
