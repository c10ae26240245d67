"""Open ends under backflow: the static-pressure ends' convective term (theory §10, "Open ends under backflow").

The term ½ρ_f ∫_Γe J κ(a·n) ū·q, κ(x) = x − β min(x, 0), is checked as a form (its matrix against the
ledger's quadrature), in the step's identity (which closes with its two columns on a moving wall with flow
entering both ends), and on a run where the flow reverses: without the backflow term (β = 0) the energy
grows beyond the work put in; with it the run is bounded and its outlet velocity stays physical, where
total-pressure ends let the outlet's centreline velocity run away.
"""

import numpy as np
import pytest
from fluid_steps import BE, given, setup_fluid

from multilayer.case.casefile import load_case
from multilayer.fluid.contract import Domain, Interface
from multilayer.results.reading import read_run
from multilayer.runner.loop import run_case
from multilayer_plugins.channel import NavierStokes, forms
from multilayer_plugins.channel.end_convection import end_convection, end_kinetic_flux

RHO = 1.06


def step_with_inflow(**params):
    """A Navier–Stokes step on a deformed, moving channel whose flow enters both ends near the wall."""
    fluid = NavierStokes(RHO, 0.035, **params)
    step = setup_fluid(fluid, 2.0, 0.5, nz=8, nr=3)
    z = fluid.line.z
    eta, v = 0.02 * np.sin(np.pi * z / 2.0), 0.5 * np.sin(np.pi * z / 2.0)
    # u_z = 1 − 12 r²: out along the axis, back in near the wall (r > 0.29), at both ends
    state = fluid.initial_state(lambda zz, rr: (1.0 - 12 * rr**2 + 0.1 * np.sin(3 * zz), 0.05 * rr * np.cos(zz)), eta)
    dt = 1e-3
    M = 0.11 * np.eye(fluid.line.ndofs)
    given(fluid, p_in=50.0, p_out=10.0)
    system = fluid.system([state], Domain(eta + 0.5 * dt * v, v), BE, dt, (0.0, dt), interface=Interface(M / dt, M @ v / dt))
    return fluid, step, system, eta, eta + dt * v


def columns(terms):
    return {k: v for k, v in terms.items() if k.endswith((".convection", ".backflow"))}


@pytest.mark.parametrize("beta", [0.0, 1.0, 2.5])
def test_the_identity_closes_with_the_ends_columns(beta):
    fluid, step, system, eta_old, eta_new = step_with_inflow(ends="static-pressure", backflow=beta)
    solution = fluid.solve(system)
    terms = fluid.identity(system, solution, eta_old, eta_new)
    assert abs(terms["a2.residual"]) <= 1e-12 * terms["a2.scale"]  # measured 7e-16
    ends = columns(terms)
    assert set(ends) == {f"dissipation.{e}.{c}" for e in ("inlet", "outlet") for c in ("convection", "backflow")}
    for end in ("inlet", "outlet"):
        convection, backflow = ends[f"dissipation.{end}.convection"], ends[f"dissipation.{end}.backflow"]
        assert convection < 0.0  # more kinetic energy comes in near the wall than leaves along the axis
        if beta == 0.0:
            assert backflow == 0.0
        else:
            assert backflow > 0.0
        if beta >= 1.0:
            assert convection + backflow >= 0.0  # the energy estimate: nothing comes in with the flow
    # the term is in the solve: dropping the columns leaves the identity open by their sum
    assert abs(terms["a2.residual"] - sum(ends.values())) > 1e-6 * terms["a2.scale"]


def test_the_matrix_is_the_ledgers_quadrature():
    """ū·K_e ū Δt, K_e the term's assembled entries, equals the two columns from the fields' quadrature."""
    fluid, step, system, eta_old, eta_new = step_with_inflow(ends="static-pressure", backflow=1.7)
    ends = step.ends
    rng = np.random.default_rng(3)
    ubar = rng.standard_normal(step.channel.nu)
    a = system.scheme.extrapolate([s.u for s in system.history])
    data = np.zeros(step.pattern.nnz)
    ends.convection.add_matrix(data, a, ends.stretches(system.fields))
    K = step.pattern.matrix(data)[: step.channel.nu, : step.channel.nu]
    quadrature = ends.convection_ledger(ubar, a, system.fields, system.dt)
    assert system.dt * float(ubar @ K @ ubar) == pytest.approx(sum(quadrature.values()), rel=1e-12)
    # and the matrix is symmetric: the term adds no skew part to the step
    assert abs(K - K.T).max() <= 1e-14 * abs(K).max()


def test_the_facet_tables_are_the_scikit_fem_forms():
    """The step's contraction of the precomputed facet tables against the forms assembled by scikit-fem."""
    fluid, step, system, eta_old, eta_new = step_with_inflow(ends="static-pressure", backflow=1.3)
    convection, nu = step.ends.convection, step.channel.nu
    rng = np.random.default_rng(5)
    a, ubar = rng.standard_normal(nu), rng.standard_normal(nu)
    stretches = {"inlet": 1.02, "outlet": 0.97}
    data = np.zeros(step.pattern.nnz)
    convection.add_matrix(data, a, stretches)
    ours = step.pattern.matrix(data)[:nu, :nu]
    theirs, columns = 0.0, {}
    for end, basis in {"inlet": step.channel.inlet, "outlet": step.channel.outlet}.items():
        flux = np.asarray(forms.dot(basis.interpolate(a), basis.normals))
        kappa = convection.kappa(flux)
        assert np.allclose(flux, convection.normal_velocity(end, a), rtol=0, atol=1e-13 * np.abs(flux).max())
        theirs = theirs + 0.5 * RHO * end_convection.assemble(basis, J=stretches[end], kappa=kappa)
        u = basis.interpolate(ubar)
        kinetic = 0.5 * RHO * 1e-3 * stretches[end]
        columns[f"dissipation.{end}.convection"] = kinetic * end_kinetic_flux.assemble(basis, u=u, J=1.0, kappa=flux)
        columns[f"dissipation.{end}.backflow"] = 1.3 * kinetic * end_kinetic_flux.assemble(
            basis, u=u, J=1.0, kappa=-np.minimum(flux, 0.0))
    theirs = theirs[:nu, :nu]
    assert abs(ours - theirs).max() <= 1e-13 * abs(theirs).max()
    ledger = convection.ledger(ubar, a, stretches, 1e-3)
    assert ledger == pytest.approx(columns, rel=1e-12)


def test_total_pressure_ends_have_no_term():
    fluid, step, system, eta_old, eta_new = step_with_inflow(ends="total-pressure")
    assert step.ends.convection is None
    terms = fluid.identity(system, fluid.solve(system), eta_old, eta_new)
    assert not columns(terms) and abs(terms["a2.residual"]) <= 1e-12 * terms["a2.scale"]


def test_parameters_are_checked():
    with pytest.raises(ValueError, match=r"fluid.backflow = 0.5 .* set fluid.ends = \"static-pressure\""):
        NavierStokes(1.0, 0.035, ends="total-pressure", backflow=0.5)
    with pytest.raises(ValueError, match="fluid.ends must be one of"):
        NavierStokes(1.0, 0.035, ends="dynamic")
    with pytest.raises(ValueError, match="fluid.backflow must be ≥ 0"):
        NavierStokes(1.0, 0.035, backflow=-1.0)
    assert NavierStokes(1.0, 0.035).backflow == 1.0
    assert NavierStokes(1.0, 0.035, ends="total-pressure").backflow is None


REVERSING = """
title = "a flow rate that reverses, into a rigid tube with its outlet at p = 0"
fluid = {{ model = "navier-stokes", density = 1.06, viscosity = 0.035 }}
[geometry]
model = "axisymmetric"
length = 6.0
radius = 0.3
[mesh]
nz = 20
nr = 3
order = 2
[time]
end = {end}
dt = 1e-3
[coupler]
model = "fluid-only"
[loads]
inlet = {{ model = "flow-rate", flow = {{ model = "sine", amplitude = 20.0, frequency = 2.0 }} }}
outlet = {outlet}
[output]
every = 0
probes = [
  {{ name = "q_out", quantity = "flow_rate", z = 6.0 }},
  {{ name = "uz_out", quantity = "u_z", z = 6.0, r = 0.0 }},
]
"""


WINDKESSEL = '{ model = "windkessel", proximal = 2400.0, capacitance = 3.0e-5, distal = 1.47e4 }'


def run_reversing(tmp_path, name, end, *sets, outlet="0.0"):
    path = tmp_path / "reversing.toml"
    path.write_text(REVERSING.format(end=end, outlet=outlet))
    result = run_case(load_case(path, sets), tmp_path / name)
    return result, read_run(name, tmp_path / name).series


def test_without_the_backflow_term_the_energy_grows_beyond_the_work(tmp_path):
    """β = 0, the plain do-nothing end: the kinetic energy the flow brings in is unbounded (the run stops at
    t = 0.089 s, measured); β = 1 runs the same steps and on through the reversal.  Under SUPG alone: grad-div's
    dissipation (the default γ = 0.1) outweighs what this short run brings in, and it runs to 0.4 s ok."""
    result, _ = run_reversing(tmp_path, "plain", 0.15, "fluid.backflow=0", "fluid.grad_div=0")
    assert result.status == "failed" and "energy grew beyond the work" in result.reason, result.reason


@pytest.mark.parametrize("outlet", ["0.0", WINDKESSEL])
def test_with_the_backflow_term_reversing_flow_stays_bounded(tmp_path, outlet):
    """Q = 20 sin(4πt) cm³/s, mean velocity ≤ 20/(π 0.3²) = 71 cm/s, reversing at t = 0.25 s, into a pressure
    or an RCR outlet (the rigid tube's velocity is the same).  Measured over 0.4 s: the outlet's centreline u_z
    within −76…104 cm/s (total-pressure ends: −453…462), the outlet's backflow column 4.9e3 erg while the flow
    comes back in; β = 0 under SUPG alone stops at t = 0.094 s with the RCR outlet."""
    result, s = run_reversing(tmp_path, "stabilized", 0.4, outlet=outlet)
    assert result.status == "ok", result.reason
    assert np.all(np.abs(s["energy.relative_residual"]) <= 1e-9)
    back = s["t"] > 0.26
    assert np.all(s["q_out"][back] < 0.0)  # the flow does come back in through the outlet
    assert np.max(np.abs(s["uz_out"])) < 2.0 * 20.0 / (np.pi * 0.3**2)  # a Poiseuille profile's centreline: 2×
    outlet = s["dissipation.outlet.convection"] + s["dissipation.outlet.backflow"]
    assert np.all(outlet >= -1e-12 * np.max(np.abs(outlet)))  # β = 1: no kinetic energy comes in with the flow
    assert np.sum(s["dissipation.outlet.backflow"][back]) > 0.5 * np.sum(np.abs(s["dissipation.outlet.convection"][back]))
