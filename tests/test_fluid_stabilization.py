"""SUPG (and grad-div) of the Navier–Stokes step (theory §5, "Stabilization"): consistent, in the ledger, and
what they are for — no node-to-node oscillation at an artery's cell Péclet number.

Consistency: the stabilization's rows, (A_supg − A_galerkin) x − (b_supg − b_galerkin), vanish at
Poiseuille flow (P2 holds it exactly; ∇p = μΔu, a·∇u = 0, ∇·u = 0) in the planar channel and the
tube, rigid or uniformly dilated — to round-off (measured ≤ 4e-16 of the rows' scale).

A manufactured field checks each part of the residual: for u quadratic and p linear (exact in P2/P1)
the rows equal ∫ J τ_M ((a·∇)φ_i)·R_M with R_M computed by hand (time difference, convection, the
cylindrical vector Laplacian, ∇p) at the quadrature points, to ≤ 4e-16 of the rows' scale (the rows
themselves ~8e-2 of it; leaving out the Laplacian's −u_r/r² or the old level fails by ≥ 2e-3).

Womersley flow: the Galerkin Navier–Stokes step does not have it as its solution (the dynamic-pressure
end effect of tests/test_fluid_poiseuille.py, here 2.6e-2 planar and 3.8e-2 in the tube at Re ≈ 23),
so the stabilization is measured against the Galerkin step on the same mesh: their difference
(relative L², BE, Δt = T/20, 4 steps, nz = nr = 4, 8, 16) is 5.26e-4, 1.04e-4, 1.61e-5 planar and
6.86e-4, 1.46e-4, 2.30e-5 in the tube — below the end effect, and falling at orders 2.69 and 2.66
from 8 to 16.  The Stokes Womersley orders (tests/test_fluid_womersley.py, tests/test_axisymmetric_fluid.py) do not see
the stabilization, which only the ``navier-stokes`` fluid has.

The oscillation: a rigid tube R = 0.3 cm (the carotid's), ρ = 1.06, μ = 0.035, a flow rate of
20 cm³/s from rest (mean velocity 71 cm/s: a cell Péclet number |u| h_z / 2ν ≈ 650 on 10 × 2
cells), BDF2, Δt = 1e-3 s, 100 steps, SUPG and grad-div as by default (grad_div = 0.1): the centreline
u_z over the mean velocity at z = 0.5 … 5.5 spans [−17.1, 15.4] without stabilization and [0.76, 1.45]
with it.
"""

import numpy as np
import pytest
from fluid_steps import given, setup_fluid
from test_axisymmetric_fluid import womersley_pipe
from test_fluid_womersley import OMEGA, PERIOD, march, womersley

from multilayer.fluid.contract import Domain, Interface
from multilayer.functions.loads import ConstantPressure
from multilayer.numerics.timescheme import named, stage_schemes
from multilayer_plugins.axisymmetric import Axisymmetric
from multilayer_plugins.channel import NavierStokes, Stokes
from multilayer_plugins.channel.probes import l2_error
from multilayer_plugins.flow_rate import FlowRate
from multilayer_plugins.planar import Planar

RHO, MU = 1.06, 0.035
GEOMETRIES = {"planar": Planar(), "tube": Axisymmetric()}


def fluid_pair(geometry, wall, L=2.0, R=0.5, nz=4, nr=3, ends=None):
    """The stabilized and the Galerkin Navier–Stokes fluid on one channel."""
    pair = []
    for kind in ("supg", "none"):
        fluid = NavierStokes(RHO, MU, stabilization=kind)
        setup_fluid(fluid, L, R, nz=nz, nr=nr, order=2, wall=wall, geometry=geometry, ends=ends)
        pair.append(fluid)
    return pair


def stabilization_rows(pair, history, domain, scheme, dt, x):
    """(A_supg − A_none) x − (b_supg − b_none) on the velocity rows, and the scale of its terms."""
    rows, scale, systems = [], 0.0, []
    for fluid in pair:
        system = fluid.system(history, domain, scheme, dt, (0.0, dt))
        systems.append(system)
        A = fluid.discrete.pattern.matrix(system.own)
        rows.append(A @ x - system.own_rhs)
        scale = max(scale, float(np.max(np.abs(A) @ np.abs(x))), float(np.max(np.abs(system.own_rhs))))
    nu = pair[0].channel.nu
    return (rows[0] - rows[1])[:nu], scale, systems[0]


@pytest.mark.parametrize("dilation", [0.0, 0.1])
@pytest.mark.parametrize("name", sorted(GEOMETRIES))
def test_the_stabilization_vanishes_on_poiseuille_flow(name, dilation):
    geometry, R, L, dp = GEOMETRIES[name], 0.5, 2.0, 50.0
    wall = "rigid" if dilation == 0.0 else "prescribed"
    pair = fluid_pair(geometry, wall, L, R)
    wide = R + dilation
    k = geometry.radial_power
    U = dp * wide**2 / (2 * (1 + k) * MU * L)  # u_z = U (1 − r²/(R + c)²), ∂p/∂z = −dp/L
    state = pair[0].initial_state(lambda z, r: (U * (1 - r**2 / wide**2), 0 * r),
                                  eta=np.full(pair[0].line.ndofs, dilation))
    ch = pair[0].channel
    p = dp * (1 - ch.pressure.doflocs[0] / L)
    state = type(state)(state.u, p, state.v, state.ends)
    x = np.concatenate([state.u, p])
    eta = np.full(pair[0].line.ndofs, dilation)
    domain = Domain(eta, np.zeros_like(eta))
    for scheme in ("backward-euler", "bdf2", "crank-nicolson"):
        rows, scale, system = stabilization_rows(pair, [state, state], domain, named(scheme), 1e-3, x)
        assert system.stabilized is not None and np.max(system.stabilized.tau_m) > 0.0
        assert np.max(np.abs(rows)) <= 1e-12 * scale, (scheme, np.max(np.abs(rows)) / scale)


def test_the_stabilization_is_not_zero_off_a_solution():
    """The control of the test above: a Poiseuille profile with the wrong pressure gradient is not a
    solution, and the stabilization's rows see it (8.8e-7 of the rows' scale, 1e9 times the round-off above)."""
    pair = fluid_pair(Planar(), "rigid")
    state = pair[0].initial_state(lambda z, r: (10.0 * (0.25 - r**2), 0 * r))
    ch = pair[0].channel
    x = np.concatenate([state.u, 3.0 * (1 - ch.pressure.doflocs[0] / 2.0)])
    still = Domain.still(pair[0].line.ndofs)
    rows, scale, _ = stabilization_rows(pair, [state], still, named("backward-euler"), 1e-3, x)
    assert np.max(np.abs(rows)) > 1e-8 * scale  # measured 8.8e-7


@pytest.mark.parametrize("scheme", sorted(stage_schemes()))  # every stage of every registered scheme
@pytest.mark.parametrize("name", sorted(GEOMETRIES))
def test_the_ledger_closes_with_the_stabilization_columns(name, scheme):
    """A moving, deformed channel with a Robin wall: the step tested with ū closes with SUPG's and grad-div's
    columns (each by quadrature of the solved fields), and without either it does not."""
    S = stage_schemes()[scheme]
    fluid = NavierStokes(1.0, 0.035, grad_div=1.0)
    setup_fluid(fluid, 2.0, 0.5, nz=8, nr=3, geometry=GEOMETRIES[name])
    z, n = fluid.line.z, fluid.line.ndofs
    eta, v = 0.02 * np.sin(np.pi * z / 2.0), 0.5 * np.sin(np.pi * z / 2.0)
    state = fluid.initial_state(lambda zz, rr: (60.0 * (1.0 - 4 * rr**2) + 5 * np.sin(3 * zz), 2.0 * rr * np.cos(zz)),
                                eta)
    dt, M = 1e-3, 0.11 * np.eye(n)
    given(fluid, p_in=500.0, p_out=100.0)
    interface = Interface((S.inertia / dt) * M, -(M @ S.history([v])) / dt)
    solution, terms = fluid.step([state, state], Domain(eta + S.geometry_position * dt * v, v), S, dt, (0.0, dt),
                                 interface, eta, eta + dt * v)
    supg, grad_div = terms["dissipation.stabilization.fluid"], terms["dissipation.grad_div.fluid"]
    assert abs(terms["a2.residual"]) <= 1e-12 * terms["a2.scale"]
    assert grad_div > 0.0
    for term in (supg, grad_div):
        assert abs(term) > 1e-6 * terms["a2.scale"]
    galerkin = NavierStokes(1.0, 0.035, stabilization="none")
    setup_fluid(galerkin, 2.0, 0.5, nz=8, nr=3, geometry=GEOMETRIES[name])
    given(galerkin, p_in=500.0, p_out=100.0)
    _, plain = galerkin.step([state, state], Domain(eta + S.geometry_position * dt * v, v), S, dt, (0.0, dt),
                             interface, eta, eta + dt * v)
    assert "dissipation.stabilization.fluid" not in plain and "dissipation.grad_div.fluid" not in plain
    assert abs(plain["a2.residual"]) <= 1e-12 * plain["a2.scale"]


def test_stokes_has_no_stabilization():
    fluid = Stokes(RHO, MU)
    setup_fluid(fluid, 2.0, 0.5, nz=2, nr=2)
    assert fluid.discrete.stabilization is None


def test_bad_stabilization_parameters_are_refused():
    with pytest.raises(ValueError, match="stabilization must be one of supg, none, got 'spug'"):
        NavierStokes(RHO, MU, stabilization="spug")
    with pytest.raises(ValueError, match="grad_div must be ≥ 0"):
        NavierStokes(RHO, MU, grad_div=-1.0)


def tau_m(dt, supg_dt=None, scheme="backward-euler"):
    """τ_M at the quadrature points of a Navier–Stokes step of ``dt`` from rest in a dilated channel."""
    fluid = NavierStokes(RHO, MU, supg_dt=supg_dt)
    setup_fluid(fluid, 2.0, 0.5, nz=4, nr=3)
    state = fluid.initial_state(lambda z, r: (60.0 * (0.25 - r**2), 0 * r))
    still = Domain.still(fluid.line.ndofs)
    return fluid.system([state, state], still, named(scheme), dt, (0.0, dt)).stabilized.tau_m


def test_supg_dt_sets_tau_m_on_every_longer_step_and_leaves_shorter_ones_their_own():
    """``supg_dt`` = Δt_τ: τ_M's rate is max(ϱ, 1/Δt_τ), so every step longer than Δt_τ solves one stabilized
    problem (an adaptive run's estimate then sees all the error that changes with the step), a shorter one keeps
    its own τ_M (τ_M ϱ ≤ ½), and without it each step has its own."""
    at = tau_m(1e-4)
    for dt in (1e-3, 2e-3):
        assert np.array_equal(tau_m(dt, supg_dt=1e-4), at)
        assert np.all(tau_m(dt) > 5.0 * at)  # each step's own: ∝ Δt where the time term dominates
    assert np.array_equal(tau_m(5e-5, supg_dt=1e-4), tau_m(5e-5))
    assert np.array_equal(tau_m(1e-3, supg_dt=1e-4, scheme="bdf2"), at)  # the rate, not the scheme's Δt
    with pytest.raises(ValueError, match="supg_dt must be > 0"):
        NavierStokes(RHO, MU, supg_dt=0.0)


def centreline_ratio(kind, nz, nr, Q=20.0, steps=100, dt=1e-3, L=6.0, R=0.3):
    """min and max of the centreline u_z over the mean velocity Q/(πR²) at z = 0.5 … 5.5 over the run (a rigid
    tube fed a flow rate Q from rest, BDF2), and the largest ledger residual."""
    fluid = NavierStokes(RHO, MU, stabilization=kind)
    setup_fluid(fluid, L, R, nz, nr, geometry=Axisymmetric(), wall="rigid",
                ends={"inlet": FlowRate(ConstantPressure(Q))})
    S, still = named("bdf2"), Domain.still(fluid.line.ndofs)
    history, t = [fluid.initial_state()], 0.0
    z = np.linspace(0.5, 5.5, 11)
    lo, hi, residual = np.inf, -np.inf, 0.0
    for _ in range(steps):
        solution, terms = fluid.step(history, still, S, dt, (t, t + dt))
        history, t = [solution.state, history[0]], t + dt
        ratio = fluid.velocity(solution.state, None, z, 0 * z)[0] / (Q / (np.pi * R**2))
        lo, hi = min(lo, ratio.min()), max(hi, ratio.max())
        residual = max(residual, abs(terms["a2.residual"]) / terms["a2.scale"])
    return lo, hi, residual


def test_the_stabilization_removes_the_oscillation_of_an_artery_flow():
    lo, hi, residual = centreline_ratio("supg", 10, 2)
    assert 0.0 < lo and hi < 2.5, (lo, hi)  # measured 0.76, 1.45
    assert residual < 1e-11
    lo, hi, _ = centreline_ratio("none", 10, 2)
    assert lo < -5.0 and hi > 5.0, (lo, hi)  # measured −17.1, 15.4: the control


def womersley_difference(geometry, n, G=10.0, dt=PERIOD / 20, steps=4):
    """Relative L² difference of the stabilized and the Galerkin Navier–Stokes step on Womersley flow (BE's
    exact periodic profile as the start), and the Galerkin step's distance from that profile."""
    lam = (1 - np.exp(-1j * OMEGA * dt)) / dt
    exact = (womersley_pipe if geometry.radial_power else womersley)(G, lam)
    states = []
    for fluid in fluid_pair(geometry, "rigid", L=1.0, R=0.5, nz=n, nr=n):
        state, t = march(fluid, exact, G, dt, steps, "backward-euler")
        states.append(state)
    ch, eta = fluid.channel, np.zeros(fluid.line.ndofs)
    scale = l2_error(ch, 0 * state.u, eta, exact(t))
    zero = lambda z, r: (0 * r, 0 * r)  # noqa: E731
    return (l2_error(ch, states[0].u - states[1].u, eta, zero) / scale,
            l2_error(ch, states[1].u, eta, exact(t)) / scale)


@pytest.mark.parametrize("name", sorted(GEOMETRIES))
def test_the_stabilization_of_womersley_flow_is_below_the_end_effect_and_falls_under_refinement(name):
    """Planar 5.26e-4, 1.04e-4, 1.61e-5 (the Galerkin step 0.104 off the profile); tube 6.86e-4, 1.46e-4,
    2.30e-5 (0.102): orders 2.69 and 2.66 from nz = nr = 8 to 16."""
    differences, ends = zip(*[womersley_difference(GEOMETRIES[name], n) for n in (4, 8, 16)])
    assert np.all(np.array(differences) < 0.4 * np.array(ends)), (differences, ends)
    assert np.log2(differences[1] / differences[2]) > 1.8, differences


def manufactured(c):
    """A quadratic velocity (u_z, u_r) and a linear pressure, in physical coordinates; u_r = 0 on the axis."""
    def u(z, r):
        return (c[0] + c[1] * z + c[2] * r**2 + c[3] * z * r + c[4] * z**2, r * (c[5] + c[6] * z + c[7] * r))

    def p(z, r):
        return c[8] + c[9] * z + c[10] * r

    def residual_parts(z, r, k):
        """(u, (a·∇)-ready gradient rows, vector Laplacian, ∇p) at physical points, k the radial power."""
        uz, ur = u(z, r)
        grad_z = (c[1] + c[3] * r + 2 * c[4] * z, 2 * c[2] * r + c[3] * z)
        grad_r = (r * c[6], c[5] + c[6] * z + 2 * c[7] * r)
        lap_z = 2 * c[4] + 2 * c[2] + k * grad_z[1] / r
        lap_r = 2 * c[7] + k * grad_r[1] / r - k * ur / r**2
        return (uz, ur), (grad_z, grad_r), (lap_z, lap_r), (c[9] + 0 * z, c[10] + 0 * z)

    return u, p, residual_parts


@pytest.mark.parametrize("dilation", [0.0, 0.05])
@pytest.mark.parametrize("name", sorted(GEOMETRIES))
def test_each_part_of_the_momentum_residual(name, dilation):
    """The SUPG rows equal ∫ J τ_M ((a·∇)φ_i)·R_M with R_M = ρ(ū − uⁿ)/Δt + ρ(a·∇)ū − μΔū + ∇p̄ written by hand
    (the cylindrical vector Laplacian in the tube), for quadratic ū, uⁿ and a linear p̄ (exact in P2/P1)."""
    geometry, k, dt = GEOMETRIES[name], GEOMETRIES[name].radial_power, 1e-3
    rng = np.random.default_rng(3)
    new, old = manufactured(rng.uniform(-1, 1, 11) * 10), manufactured(rng.uniform(-1, 1, 11) * 10)
    pair = []
    for gd in (0.0, None):
        fluid = NavierStokes(RHO, MU, stabilization="supg" if gd is not None else "none", grad_div=gd or 0.0)
        setup_fluid(fluid, 2.0, 0.5, nz=3, nr=3, order=2, wall="rigid" if dilation == 0.0 else "prescribed",
                    geometry=geometry)
        pair.append(fluid)
    ch = pair[0].channel
    eta = np.full(pair[0].line.ndofs, dilation)
    state_old = pair[0].initial_state(old[0], eta=eta)
    ubar = pair[0].initial_state(new[0], eta=eta).u
    s = (0.5 + dilation) / 0.5
    pz, pr = ch.pressure.doflocs
    x = np.concatenate([ubar, new[1](pz, s * pr)])
    rows, scale, system = stabilization_rows(pair, [state_old], Domain(eta, np.zeros_like(eta)),
                                             named("backward-euler"), dt, x)
    stab = system.stabilized
    # the rows by hand: quadrature points in physical coordinates, the test functions' physical gradients
    X = ch.velocity.global_coordinates()
    z, r = np.asarray(X[0]), s * np.asarray(X[1])
    (uz, ur), (gz_, gr_), (lz, lr), (dpz, dpr) = new[2](z, r, k)
    (oz, orr), _, _, _ = old[2](z, r, k)
    a = stab.a
    R_z = RHO * (uz - oz) / dt + RHO * (a[0] * gz_[0] + a[1] * gz_[1]) - MU * lz + dpz
    R_r = RHO * (ur - orr) / dt + RHO * (a[0] * gr_[0] + a[1] * gr_[1]) - MU * lr + dpr
    weight = ch.velocity.dx * system.fields.J * stab.tau_m
    expected = np.zeros(ch.nu)
    for i, (phi,) in enumerate(ch.velocity.basis):
        grad = np.asarray(phi.grad)  # (component, direction (ẑ, r̂), e, q)
        transport = a[0] * grad[:, 0] + a[1] * grad[:, 1] / s  # (a·∇)φ_i, ∂_r = ∂_r̂ / s
        local = np.sum(weight * (transport[0] * R_z + transport[1] * R_r), axis=1)
        np.add.at(expected, ch.velocity.element_dofs[i], local)
    assert np.max(np.abs(expected)) > 1e-3 * scale  # not a vacuous comparison
    assert np.max(np.abs(rows - expected)) <= 1e-11 * scale, np.max(np.abs(rows - expected)) / scale


def self_convergence(geometry, kind, meshes=(4, 8, 16), reference=32):
    """‖u_n − u_ref‖ of Navier–Stokes Womersley flow (BE, Δt = T/20, 4 steps from BE's exact periodic profile)
    on nz = nr = n against the same fluid on nz = nr = ``reference``: the convergence of the step as it is, ends
    included (the Womersley profile is not its solution at an end the flow re-enters, so not against that)."""
    lam = (1 - np.exp(-1j * OMEGA * (PERIOD / 20))) / (PERIOD / 20)
    exact = (womersley_pipe if geometry.radial_power else womersley)(10.0, lam)
    runs = {}
    for n in (*meshes, reference):
        fluid = NavierStokes(RHO, MU, stabilization=kind)
        setup_fluid(fluid, 1.0, 0.5, nz=n, nr=n, order=2, wall="rigid", geometry=geometry)
        runs[n] = (fluid, march(fluid, exact, 10.0, PERIOD / 20, 4, "backward-euler")[0])
    fine_fluid, fine_state = runs[reference]

    def fine(z, r):
        u = fine_fluid.velocity(fine_state, None, z.ravel(), r.ravel())
        return u[0].reshape(z.shape), u[1].reshape(z.shape)

    return np.array([l2_error(runs[n][0].channel, runs[n][1].u, np.zeros(runs[n][0].line.ndofs), fine)
                     for n in meshes])


@pytest.mark.parametrize("name", sorted(GEOMETRIES))
def test_the_stabilized_step_converges_as_the_galerkin_step_on_womersley_flow(name):
    """P2 Womersley flow in space, SUPG and grad-div (the defaults) against the Galerkin step, each against its
    own 32 × 32 run: errors 5.04e-3, 1.52e-3, 3.09e-4 and 5.05e-3, 1.53e-3, 3.14e-4 planar (orders 1.73, 2.30 and
    1.72, 2.29: the reference's own error lowers the last), 8.81e-3, 2.83e-3, 6.45e-4 and 8.82e-3, 2.85e-3,
    6.50e-4 in the tube (1.64, 2.13 both): the stabilization leaves the orders as they are."""
    stabilized, galerkin = (self_convergence(GEOMETRIES[name], kind) for kind in ("supg", "none"))
    orders = [np.log2(e[:-1] / e[1:]) for e in (stabilized, galerkin)]
    assert np.all(np.abs(orders[0] - orders[1]) < 0.05), orders
    assert np.all(orders[0] > 1.5), orders
    assert np.all(np.abs(stabilized / galerkin - 1) < 0.02), (stabilized, galerkin)
