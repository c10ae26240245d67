"""The fluid under an axial mesh motion (no-slip at a thick first layer), planar and axisymmetric.

The lumen moves by η = a sin(πz/L) sin(2πt/T₀) radially and
d_z = b sin(2πz/L) sin(2πt/T₀) axially; the fluid domain follows by
X̂ + (D_z, r̂η/R) with D_z the harmonic extension of d_z
(:mod:`multilayer_plugins.channel.extension`), and its wall velocity is the
lumen's in both components (prescribed mode).

- **d_z = 0** gives the radial map's fields and the same step to round-off.
- **Geometric conservation.** ∫ J is the domain's volume (the quadrature
  integrates det F · rᵏ exactly), so the moving-domain term's rate, the exact
  difference quotient of J, integrates to the volume the lumen sweeps over
  the step: V = ∫ W(R + η) (1 + d_z') dẑ along the lumen, W(r) = ∫₀ʳ weight
  (r planar, πr² in a tube), to round-off.
- **Mass balance.** The divergence row against π = 1 is exact (degree 4
  planar, 7 in a tube, as for the radial map: the cofactor of F has degree
  ≤ 2), so Q_in − Q_out is the flux of the wall velocity through the
  lumen of the step's domain, ∫ weight(r) (−η' v_z + (1 + d_z') v) dẑ, to
  round-off.
- **Energy identity.** The step's identity closes to round-off with the
  prescribed wall's work, the kinetic energies on the axially moved domains.
"""

import attrs
import numpy as np
import pytest
import skfem
from fluid_steps import BE, given, setup_fluid

from multilayer.fluid.contract import Domain
from multilayer.numerics.linsolve import Reuse
from multilayer.numerics.timescheme import named
from multilayer_plugins.axisymmetric import Axisymmetric
from multilayer_plugins.channel import NavierStokes, Stokes
from multilayer_plugins.channel.ale import ALEFields
from multilayer_plugins.channel.ledger import end_fluxes
from multilayer_plugins.planar import Planar

L, R, MU, RHO = 2.0, 0.5, 0.035, 1.0
A, B, T0 = 0.05, 0.03, 0.1
GEOMETRIES = {"planar": Planar(), "axisymmetric": Axisymmetric()}


def lumen_law(t, z, b=B):
    """(η, d_z) of the lumen at time t (cm), d_z of amplitude ``b``."""
    s = np.sin(2 * np.pi * t / T0)
    return A * np.sin(np.pi * z / L) * s, b * np.sin(2 * np.pi * z / L) * s


def line_integral(fluid, integrand, *vectors):
    """∫₀ᴸ integrand(values, derivatives) dẑ of line vectors, exactly for these polynomials (Gauss, degree 12)."""
    basis = skfem.Basis(fluid.line.basis.mesh, fluid.line.basis.elem, intorder=12)
    fields = [basis.interpolate(x) for x in vectors]
    values = [np.asarray(f) for f in fields]
    slopes = [np.asarray(f.grad[0]) for f in fields]
    return float(np.sum(basis.dx * integrand(values, slopes)))


def volume(fluid, eta, d_z):
    """The domain's volume from its lumen: ∫ W(R + η)(1 + d_z') dẑ."""
    geometry = fluid.channel.geometry
    W = (lambda r: np.pi * r ** 2) if geometry.radial_power else (lambda r: r)
    return line_integral(fluid, lambda x, dx: W(R + x[0]) * (1.0 + dx[1]), eta, d_z)


def wall_flux(fluid, eta, d_z, v, v_z):
    """∫ weight(r) (−η' v_z + (1 + d_z') v) dẑ: the wall velocity's flux out through the lumen of (η, d_z)."""
    weight = fluid.channel.geometry.weight
    return line_integral(fluid, lambda x, dx: weight(R + x[0]) * (-dx[0] * x[3] + (1.0 + dx[1]) * x[2]),
                         eta, d_z, v, v_z)


def march(cls, geometry, order, steps, dt=T0 / 20, scheme=BE, axial=True, b=B, nz=8, nr=3):
    """Steps of a fluid in a prescribed lumen motion (radial map only unless ``axial``); a record per step."""
    fluid = cls(RHO, MU)
    setup_fluid(fluid, L, R, nz=nz, nr=nr, order=order, wall="prescribed", geometry=GEOMETRIES[geometry],
                reuse=Reuse("none"))
    z = fluid.line.z
    state, t, records = fluid.initial_state(), 0.0, []
    for _ in range(steps):
        (eta, dz), (eta_new, dz_new) = lumen_law(t, z, b), lumen_law(t + dt, z, b)
        v, v_z = (eta_new - eta) / dt, (dz_new - dz) / dt
        position = scheme.geometry_position
        eta_m, dz_m = eta + position * dt * v, dz + position * dt * v_z
        domain = Domain(eta_m, v, dz_m, v_z) if axial else Domain(eta_m, v)
        given(fluid, 3.0, 1.0)
        system = fluid.system([state], domain, scheme, dt, (t, t + dt))
        solution = fluid.solve(system)
        energy = fluid.identity(system, solution, eta, eta_new, (dz, dz_new) if axial else None)
        q_in, q_out = end_fluxes(fluid.channel, system.fields, solution.mean[: fluid.channel.nu])
        records.append({"fields": system.fields, "energy": energy, "q": q_in - q_out, "old": (eta, dz),
                        "new": (eta_new, dz_new), "mid": (eta_m, dz_m), "velocity": (v, v_z), "dt": dt,
                        "u": solution.state.u})
        state, t = solution.state, t + dt
    return fluid, records


@pytest.mark.parametrize("geometry", GEOMETRIES)
@pytest.mark.parametrize("order", [1, 2])
def test_without_axial_displacement_the_fields_are_the_radial_maps(geometry, order):
    fluid = Stokes(RHO, MU)
    setup_fluid(fluid, L, R, nz=6, nr=3, order=order, wall="prescribed", geometry=GEOMETRIES[geometry])
    z, dt = fluid.line.z, 1e-3
    eta, v, zero = 0.05 * np.sin(np.pi * z / L), 0.3 * np.sin(np.pi * z / L) ** 2, np.zeros_like(z)
    radial = ALEFields.at(fluid.channel, eta, v, dt, 0.5)
    axial = ALEFields.moving(fluid.channel, fluid.discrete.extension, eta, v, zero, zero, dt, 0.5)
    eps = np.finfo(float).eps
    for name in ("J", "gz", "gr", "wr", "hoop"):
        a, b = getattr(radial, name), getattr(axial, name)
        assert (a is None and b is None) or np.abs(a - b).max() <= 4 * eps * np.abs(a).max(), name
    assert np.abs(axial.gzz - 1.0).max() <= 4 * eps and np.all(axial.grz == 0.0) and np.all(axial.wz == 0.0)
    # the rate: a difference quotient of J over Δt, so round-off of J relative to Δt |∂_t J|
    tolerance = 10 * np.finfo(float).eps * np.abs(radial.J).max() / dt
    assert np.abs(axial.dJdt - radial.dJdt).max() <= tolerance


@pytest.mark.parametrize("geometry", GEOMETRIES)
def test_without_axial_displacement_a_step_is_the_radial_maps(geometry):
    _, radial = march(NavierStokes, geometry, 2, 4, axial=False)
    _, flat = march(NavierStokes, geometry, 2, 4, axial=True, b=0.0)
    for a, b in zip(radial, flat):
        assert np.abs(a["u"] - b["u"]).max() <= 1e-12 * np.abs(a["u"]).max()
        assert a["energy"]["kinetic.fluid"] == pytest.approx(b["energy"]["kinetic.fluid"], rel=1e-13)


@pytest.mark.parametrize("geometry", GEOMETRIES)
@pytest.mark.parametrize("cls, order", [(NavierStokes, 2), (Stokes, 2), (NavierStokes, 1)])
def test_geometric_conservation_mass_balance_and_energy_identity_every_step(geometry, cls, order):
    fluid, records = march(cls, geometry, order, 20)
    dx = fluid.discrete._uu.dx
    for rec in records:
        e, dt, fields = rec["energy"], rec["dt"], rec["fields"]
        v, v_z = rec["velocity"]
        assert abs(e["a2.residual"]) <= 1e-12 * e["a2.scale"]
        # ∫ J is the volume of the domain the lumen bounds
        assert float(np.sum(dx * fields.J)) == pytest.approx(volume(fluid, *rec["mid"]), rel=1e-13)
        # the rate of J integrates to the swept volume over the step
        swept = (volume(fluid, *rec["new"]) - volume(fluid, *rec["old"])) / dt
        scale = abs(wall_flux(fluid, 0 * v, 0 * v, v, v_z)) + 1e-300
        assert float(np.sum(dx * fields.dJdt)) == pytest.approx(swept, rel=1e-11, abs=1e-11 * scale)
        # mass balance: the ends' net inflow leaves through the lumen of the step's domain
        assert rec["q"] == pytest.approx(wall_flux(fluid, *rec["mid"], v, v_z), rel=1e-11, abs=1e-11 * scale)
    assert any(abs(r["energy"]["work.wall"]) > 1e-3 * r["energy"]["a2.scale"] for r in records)
    assert max(np.abs(r["fields"].wz).max() for r in records) > 0.1 * B / T0


@pytest.mark.parametrize("geometry", GEOMETRIES)
def test_crank_nicolson_on_the_midpoint_domain_closes_its_identity_and_mass_balance(geometry):
    fluid, records = march(Stokes, geometry, 2, 10, scheme=named("crank-nicolson"))
    for rec in records:
        e = rec["energy"]
        assert abs(e["a2.residual"]) <= 1e-12 * e["a2.scale"]
        v, v_z = rec["velocity"]
        scale = abs(wall_flux(fluid, 0 * v, 0 * v, v, v_z))
        assert rec["q"] == pytest.approx(wall_flux(fluid, *rec["mid"], v, v_z), rel=1e-11, abs=1e-11 * scale)


@pytest.mark.parametrize("order", [1, 2])
def test_the_snapshot_places_the_vertices_by_the_axial_map(order):
    fluid = Stokes(RHO, MU)
    setup_fluid(fluid, L, R, nz=6, nr=3, order=order, wall="prescribed")
    eta, d_z = lumen_law(0.3 * T0, fluid.line.z)
    points, _, data = fluid.snapshot(fluid.initial_state(), eta, d_z)
    mesh = fluid.channel.mesh
    lumen = np.flatnonzero(np.abs(mesh.p[1] - R) < 1e-12)
    ends = np.flatnonzero((mesh.p[0] < 1e-12) | (mesh.p[0] > L - 1e-12))
    expected = lumen_law(0.3 * T0, mesh.p[0, lumen])
    assert np.allclose(points[lumen, 0], mesh.p[0, lumen] + expected[1], rtol=0, atol=1e-15)
    assert np.allclose(points[lumen, 1], R + expected[0], rtol=0, atol=1e-15)
    assert np.all(data["displacement"][ends, 0] == 0.0)
    assert np.abs(data["displacement"][:, 0]).max() > 0.5 * B


@pytest.mark.parametrize("geometry", GEOMETRIES)
@pytest.mark.parametrize("order", [1, 2])
def test_a_flow_rate_crosses_the_section_the_axial_map_moved(geometry, order):
    """Through any curve from the axis to the lumen, u = e_z carries W(R + η(z)) (r planar, πr² in a tube), and
    in the planar channel u = e_r carries −(D_z(z, R) − D_z(z, 0)) = D_z(z, 0) − d_z(z): the section's tilt."""
    fluid = Stokes(RHO, MU)
    setup_fluid(fluid, L, R, nz=6, nr=3, order=order, wall="prescribed", geometry=GEOMETRIES[geometry])
    eta, d_z = lumen_law(0.3 * T0, fluid.line.z)
    state = fluid.initial_state(lambda z, r: (np.ones_like(z), np.zeros_like(z)))
    tube = fluid.channel.geometry.radial_power

    def on_line(x, z):  # a line vector's value at z
        return float((fluid.line.basis.probes(np.array([[z]])) @ x)[0])

    for z in (0.4, 1.1, 1.5):
        e = on_line(eta, z)
        area = np.pi * (R + e) ** 2 if tube else R + e
        assert fluid.flow_rate(state, eta, z, d_z) == pytest.approx(area, rel=1e-13)
        probe = fluid.probe("flow_rate", z)
        assert probe(state, eta, d_z) == fluid.flow_rate(state, eta, z, d_z)
    if not tube:
        radial = fluid.initial_state(lambda z, r: (np.zeros_like(z), np.ones_like(z)))
        ext = fluid.discrete.extension
        for z in (0.4, 1.1):
            axis = float((ext.basis.probes(np.array([[z], [0.0]])) @ ext.extend(d_z))[0])
            expected = axis - on_line(d_z, z)
            assert fluid.flow_rate(radial, eta, z, d_z) == pytest.approx(expected, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("geometry", GEOMETRIES)
def test_values_at_physical_points_invert_the_axial_map(geometry):
    """A reference point X̂ moved by the map to x = X̂ + D(X̂): velocity and pressure at x are those at X̂."""
    fluid = Stokes(RHO, MU)
    setup_fluid(fluid, L, R, nz=6, nr=3, order=2, wall="prescribed", geometry=GEOMETRIES[geometry])
    eta, d_z = lumen_law(0.3 * T0, fluid.line.z)
    state = fluid.initial_state(lambda z, r: (np.sin(z) * (R - r), r * np.cos(z)))
    state = attrs.evolve(state, p=np.cos(fluid.channel.pressure.doflocs[0]))
    ext = fluid.discrete.extension
    reference = np.array([[0.3, 0.9, 1.37, 1.8], [0.1, 0.45, 0.2, 0.33]])
    D_z = ext.basis.probes(reference) @ ext.extend(d_z)
    eta_at = fluid.line.basis.probes(reference[:1]) @ eta
    z, r = reference[0] + D_z, reference[1] * (R + eta_at) / R
    u_ref = (fluid.channel.velocity.probes(reference) @ state.u).reshape(2, -1)
    p_ref = fluid.channel.pressure.probes(reference) @ state.p
    assert np.abs(D_z).max() > 0.3 * B
    assert np.allclose(fluid.velocity(state, eta, z, r, d_z), u_ref, rtol=0, atol=1e-13)
    assert np.allclose(fluid.pressure(state, eta, z, r, d_z), p_ref, rtol=0, atol=1e-13)
    assert not np.allclose(fluid.velocity(state, eta, z, r), u_ref, rtol=0, atol=1e-6)  # the radial inverse misses


def test_an_axial_displacement_at_the_ends_is_refused():
    fluid = Stokes(RHO, MU)
    setup_fluid(fluid, L, R, nz=4, nr=2, order=2, wall="prescribed")
    z = fluid.line.z
    d_z = 0.01 * z / L
    with pytest.raises(ValueError, match="must vanish at z = 0 and z = L"):
        fluid.system([fluid.initial_state()], Domain(0 * z, 0 * z, d_z, 0 * z), BE, 1e-3, (0.0, 1e-3))
