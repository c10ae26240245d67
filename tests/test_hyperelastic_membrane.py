"""The hyperelastic membranes (``neo-hookean-membrane``, ``hgo-membrane``): the laws' derivatives, the
conformance kit, the small-strain limit against the linear thin layers, the inflation against the thin-walled
closed form (a Newton solve to round-off, and the static start), Newton's quadratic convergence in a wall step,
and coupled runs of the carotid-like artery with the membrane as its intima."""

from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import skfem

from multilayer.campaign.pulse_wave import stack_long_wave_speed
from multilayer.case.casefile import validate_data
from multilayer.coupling.structure import StructureStep
from multilayer.numerics.linsolve import SolverStats
from multilayer.numerics.newton import newton
from multilayer.numerics.timescheme import named
from multilayer.plugin.problems import CaseError
from multilayer.plugin.registry import Registry
from multilayer.results.reading import read_run
from multilayer.runner.loop import run_case
from multilayer.scene.setup import Setup
from multilayer.testing import LayerConformance, force_problems
from multilayer.wall.equilibrium import lumen_force, static_deflection
from multilayer.wall.stack import LUMEN, Stack, WallSpace
from multilayer_plugins.axisymmetric import Axisymmetric
from multilayer_plugins.hyperelastic.membrane import (
    HyperelasticMembrane,
    inflation_pressure,
)
from multilayer_plugins.hyperelastic.membrane_laws import (
    MembraneLaw,
    hgo_fibre,
    neo_hookean,
)
from multilayer_plugins.planar import Planar
from multilayer_plugins.thin_shell import KoiterFamilyLayer, koiter_coefficients

REGISTRY = Registry.load()
GEOMETRIES = [Planar(), Axisymmetric()]
#: an intima-like wall: c = E/3 of the carotid's intima (E = 2 MPa); the HGO law of a media-like wall
NEO = MembraneLaw(c=6.67e5)
HGO = MembraneLaw(c=3.0e5, k1=2.4e5, k2=0.8, angle=40.0)
LAWS = {"neo-hookean": NEO, "hgo": HGO}
H, R, RHO = 0.005, 0.3, 1.06
CAROTID = Path(__file__).parents[1] / "cases" / "carotid.toml"


def membrane(law: MembraneLaw, axial_stretch: float = 1.0, **kw) -> HyperelasticMembrane:
    return HyperelasticMembrane(law, RHO, H, axial_stretch, **kw)


def line(geometry, nz: int = 8, order: int = 2, length: float = 6.0, radius: float = R) -> WallSpace:
    """The wall space of a membrane alone (its DOFs are the lumen line's)."""
    return WallSpace.build([membrane(NEO)], geometry, length, radius, nz, order)


# ---- the laws --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", LAWS)
def test_the_laws_derivatives_are_those_of_their_energy(name):
    """Ψ's gradient and Hessian in (λθ, λz) against central differences, at stretches on both sides of the fibres'
    switch I4 = 1 (compressed fibres carry nothing; the difference steps stay on one side of it)."""
    law = LAWS[name]
    rng = np.random.default_rng(3)
    x, y = rng.uniform(0.7, 1.5, 200), rng.uniform(0.8, 1.3, 200)
    e, h = law.energy(x, y), 1e-6
    px, mx, py, my = law.energy(x + h, y), law.energy(x - h, y), law.energy(x, y + h), law.energy(x, y - h)
    pairs = [(e.d_theta, (px.value - mx.value) / (2 * h)), (e.d_z, (py.value - my.value) / (2 * h)),
             (e.d_theta_theta, (px.d_theta - mx.d_theta) / (2 * h)), (e.d_theta_z, (py.d_theta - my.d_theta) / (2 * h)),
             (e.d_theta_z, (px.d_z - mx.d_z) / (2 * h)), (e.d_z_z, (py.d_z - my.d_z) / (2 * h))]
    for exact, difference in pairs:
        assert np.max(np.abs(exact - difference)) <= 1e-7 * np.max(np.abs(exact))
    if law.k1:
        I4 = x**2 * math.cos(math.radians(40.0)) ** 2 + y**2 * math.sin(math.radians(40.0)) ** 2
        assert np.any(I4 < 1.0) and np.any(I4 > 1.0)


def test_the_neo_hookean_membrane_is_the_incompressible_closed_form():
    """Ψ(λθ, λz) = c/2 (λθ² + λz² + λθ⁻²λz⁻² − 3), Ψ_θ = c(λθ − λθ⁻³λz⁻²); the fibres of k2 = 0 are
    k1 (I4 − 1)²/2 in extension, nothing in compression; the invariants' energies at their own points."""
    x, y = np.array([0.8, 1.0, 1.3]), np.array([1.0, 1.2, 0.9])
    e = NEO.energy(x, y)
    c = NEO.c
    assert np.allclose(e.value, 0.5 * c * (x**2 + y**2 + 1 / (x * y) ** 2 - 3), rtol=1e-15, atol=1e-9)
    assert np.allclose(e.d_theta, c * (x - x**-3 * y**-2), rtol=1e-15, atol=1e-9)
    assert np.allclose(e.d_z, c * (y - x**-2 * y**-3), rtol=1e-15, atol=1e-9)
    fibre = hgo_fibre(np.array([-0.5, 0.5]), 4.0, 0.0)  # at E = I4 − 1
    assert fibre.value.tolist() == [0.0, 0.5] and fibre.first.tolist() == [0.0, 2.0]
    assert neo_hookean(np.array([3.0]), c).value.tolist() == [0.0]


# ---- the conformance kit ----------------------------------------------------------------------------------------


class TestNeoHookeanMembraneConforms(LayerConformance):
    layer = "neo-hookean-membrane"


class TestHGOMembraneConforms(LayerConformance):
    layer = "hgo-membrane"


@pytest.mark.parametrize("geometry", GEOMETRIES, ids=lambda g: g.name)
@pytest.mark.parametrize("name, axial_stretch", [("neo-hookean", 1.2), ("hgo", 1.0), ("hgo", 1.1)])
def test_the_forces_are_the_energys_gradient_and_hessian_prestretched_and_with_fibres(geometry, name, axial_stretch):
    """The kit's force check (tangent against differences of the force, force against differences of W) on the
    cases the example does not reach: an axial prestretch (a force at rest) and fibres switching on and off
    between the quadrature points of one state (η up to ±0.1 cm on R = 0.3 cm: λθ from 0.7 to 1.3)."""
    layer = membrane(LAWS[name], axial_stretch, D0=5.0, D1=0.5)
    for order in (1, 2):
        space = line(geometry, nz=6, order=order).lines[LUMEN]
        forms = layer.forms(space)
        assert force_problems(forms, space.ndofs) == []
        d = 0.1 * np.random.default_rng(order).standard_normal(space.ndofs)
        eta = np.asarray(space.basis.interpolate(d))
        if layer.law.k1:
            I4 = (1 + eta / R) ** 2 * math.cos(math.radians(40.0)) ** 2 + math.sin(math.radians(40.0)) ** 2
            assert np.any(I4 < 1.0) and np.any(I4 > 1.0)
        K = forms.tangent(d)
        assert abs(K - K.T).max() <= 1e-15 * abs(K).max()  # symmetric but for the assembly's order of sums


# ---- the small-strain limit -------------------------------------------------------------------------------------


def rest_layer(layer: HyperelasticMembrane, C0: float, C1: float = 0.0) -> KoiterFamilyLayer:
    return KoiterFamilyLayer(layer.density, layer.thickness / layer.axial_stretch, C0=C0, C1=C1, D0=layer.D0,
                             D1=layer.D1)


@pytest.mark.parametrize("geometry", GEOMETRIES, ids=lambda g: g.name)
@pytest.mark.parametrize("order", [1, 2])
def test_at_rest_the_membrane_is_the_linear_thin_layer(geometry, order):
    """The tangent at rest is a Koiter-family layer's stiffness to round-off:
    neo-Hookean C0 = 4hc/R² (Koiter's membrane part, hE/(R²(1 − σ²)) at E = 3c, σ = ½), C1 = 0;
    HGO C0 = h(4c + 8k1cos⁴β)/R²; prestretched λz0: C0 = hc(1 + 3λz0⁻²)/(λz0R²), C1 = hc(λz0 − λz0⁻³) (the
    axial tension).  Mass and damping too."""
    space = line(geometry, nz=6, order=order).lines[LUMEN]
    c, k1, beta = HGO.c, HGO.k1, math.radians(HGO.angle)
    lz = 1.15
    membrane_C0 = koiter_coefficients(H, 3 * NEO.c, 0.5, R)[0] / (1 + H**2 / (12 * R**2))
    cases = [
        (membrane(NEO, D0=3.0, D1=0.2), 4 * H * NEO.c / R**2, 0.0),
        (membrane(HGO), H * (4 * c + 8 * k1 * math.cos(beta) ** 4) / R**2, 0.0),
        (membrane(NEO, lz), H * NEO.c * (1 + 3 / lz**2) / (lz * R**2), H * NEO.c * (lz - lz**-3)),
    ]
    assert abs(membrane_C0 / cases[0][1] - 1) <= 1e-15
    for layer, C0, C1 in cases:
        assert np.allclose(layer.rest_coefficients(R), (C0, C1), rtol=1e-14, atol=0)
        mine, linear = layer.forms(space), rest_layer(layer, C0, C1).forms(space)
        for part in ("mass", "damping", "stiffness"):
            a, b = getattr(mine, part), getattr(linear, part)
            assert abs(a - b).max() <= 1e-14 * abs(b).max(), part
        assert layer.long_wave_stiffness(R) == layer.rest_coefficients(R)[0]


def test_the_force_at_rest_is_zero_unless_prestretched():
    space = line(Axisymmetric()).lines[LUMEN]
    zero = np.zeros(space.ndofs)
    for law in (NEO, HGO):
        forms = membrane(law).forms(space)
        assert np.max(np.abs(forms.force(zero))) == 0.0 and forms.elastic(zero) == 0.0
    lz = 1.15  # the hoop tension at rest, h Ψ_θ(1, λz0)/(λz0 R) per unit area, pulls the line in
    forms = membrane(NEO, lz).forms(space)
    expected = H * NEO.c * (1 - lz**-2) / (lz * R) * (forms.mass @ np.ones(space.ndofs)) / (RHO * H / lz)
    assert np.allclose(forms.force(zero), expected, rtol=1e-13, atol=0) and forms.elastic(zero) == 0.0


@pytest.mark.parametrize("kind, k", [("axisymmetric", 1), ("planar", 0)])
@pytest.mark.parametrize("name", LAWS)
def test_compares_long_wave_speed_is_moens_kortewegs_with_the_rest_stiffness(kind, k, name):
    """The static compliance of the membrane alone at mid-length is 1/C0 (the rest tangent is C0 ∫ηψ: the pinned
    ends' disturbance of the projection decays within a few cells): c² = R C0/((1 + k)ρ_f)."""
    layer = {"model": f"{name}-membrane", "density": RHO, "thickness": H, "c": LAWS[name].c}
    if LAWS[name].k1:
        layer.update(k1=HGO.k1, k2=HGO.k2, angle=HGO.angle)
    case = {"geometry": {"model": kind, "length": 6.0, "radius": R}, "mesh": {"nz": 30, "nr": 4, "order": 2},
            "fluid": {"model": "navier-stokes", "density": 1.06, "viscosity": 0.035}, "layers": [layer]}
    speed = stack_long_wave_speed(case, REGISTRY).value
    exact = math.sqrt(R / (1 + k) * membrane(LAWS[name]).long_wave_stiffness(R) / 1.06)
    assert abs(speed / exact - 1) <= 1e-10  # measured 3.3e-12


# ---- inflation: the thin-walled closed form ---------------------------------------------------------------------


def inflate(space: WallSpace, layer: HyperelasticMembrane, stretch: float):
    """Newton's solve of f_int(η) = p ∫ψ((R + η)/R)ᵏ dA with p the closed form's at λθ = ``stretch`` and the end
    DOFs held at η* = (λθ − 1)R (so the uniform η* is the exact solution): (η, η*, the Newton result)."""
    forms = layer.forms(space.lines[LUMEN])
    k = space.geometry.radial_power
    p = inflation_pressure(layer, R, stretch, k)
    target = (stretch - 1.0) * R
    ends = space.lines[LUMEN].end_dofs
    free = np.setdiff1d(np.arange(space.ndofs), ends)
    basis = space.lines[LUMEN].basis

    def full(x):
        eta = np.full(space.ndofs, target)
        eta[free] = x
        return eta

    def residual(x):
        eta = full(x)
        load, internal = lumen_force(space, p, eta), forms.force(eta)
        return (load - internal)[free], (np.abs(load) + np.abs(internal))[free]

    def solve(x, r):
        eta = full(x)
        # the load on the moved lumen grows with η in a tube: its derivative p k/R ∫ λθ^(k−1) φψ dA
        moved = skfem.asm(skfem.BilinearForm(lambda u, v, w: u * v * w["s"]), basis,
                          s=k * p / R * np.asarray(basis.interpolate(1.0 + eta / R)) ** (k - 1))
        J = sp.csr_matrix(forms.tangent(eta) - moved)[free][:, free]
        return sp.linalg.spsolve(J.tocsc(), r)

    result = newton(residual, solve, np.zeros(free.size), tolerance=1e-15, max_iterations=40)
    return full(result.x), target, result


@pytest.mark.parametrize("geometry", GEOMETRIES, ids=lambda g: g.name)
@pytest.mark.parametrize("name, axial_stretch", [("neo-hookean", 1.0), ("neo-hookean", 1.15), ("hgo", 1.0),
                                                 ("hgo", 1.15)])
def test_a_newton_solve_inflates_the_membrane_to_the_closed_form(geometry, name, axial_stretch):
    """Under the closed form's pressure for λθ = 1.4 (and the ends held there) Newton's iteration from η = 0 ends
    at the uniform η* = 0.4R to round-off, quadratically (with the moved load's derivative in the tangent)."""
    layer = membrane(LAWS[name], axial_stretch)
    eta, target, result = inflate(line(geometry, nz=8, order=2), layer, 1.4)
    assert np.max(np.abs(eta - target)) <= 1e-13 * target, (np.max(np.abs(eta - target)), result.residuals)
    # once near, each residual at most 10× the square of the one before (down to the round-off floor, 1e-14)
    near = [(a, b) for a, b in zip(result.residuals, result.residuals[1:]) if a < 1e-2 and b > 1e-14]
    assert near and all(b <= 10 * a * a for a, b in near), result.residuals


def test_the_closed_form_is_laplaces_law():
    """p = σθθ t/r in a tube, σθθ = λθΨ_θ the hoop Cauchy stress of the incompressible membrane, t = h/(λθλz0),
    r = Rλθ; for the neo-Hookean law p = (hc/(Rλz0))(1 − λθ⁻⁴λz0⁻²), which tends to hc/(Rλz0)."""
    lz = 1.15
    layer = membrane(NEO, lz)
    for stretch in (1.0, 1.2, 2.0, 10.0):
        sigma = stretch * NEO.energy(np.array([stretch]), np.array([lz])).d_theta[0]
        laplace = sigma * (H / (stretch * lz)) / (R * stretch)
        p = inflation_pressure(layer, R, stretch)
        assert abs(p - laplace) <= 1e-15 * abs(p) + 1e-12
        assert abs(p - H * NEO.c / (R * lz) * (1 - stretch**-4 * lz**-2)) <= 1e-13 * H * NEO.c / R


def test_the_static_start_inflates_a_long_tube_to_the_closed_form():
    """``[initial] pressure`` on a long tube whose ends are pinned: away from the ends η is the closed form's.
    The ends' boundary layer decays over √(T_z/k_T)·R-ish lengths (the axial tension over the hoop stiffness);
    at the middle of L = 20R it has gone below the loop's tolerance."""
    layer = membrane(HGO)
    stretch = 1.3
    space = WallSpace.build([layer], Axisymmetric(), 20 * R, R, 80, 2)
    stack = Stack.assemble(space)
    p = inflation_pressure(layer, R, stretch)
    stats = SolverStats()
    eta = space.restrictions[LUMEN] @ static_deflection(stack, p, 0.0, stats)
    z = space.lines[LUMEN].z
    middle = eta[np.argmin(np.abs(z - 10 * R))]
    # measured 2.2e-11 (the static start stops at the Newton loop's tolerance, 1e-11 of the forces)
    assert abs(middle / ((stretch - 1) * R) - 1) <= 1e-10, middle
    assert stats.newton_max_iterations >= 4


# ---- Newton in a wall step ---------------------------------------------------------------------------------------

#: the membrane alone ringing from a large deflection (λθ from 0.75 to 1.25)
RINGING = {"geometry": {"model": "axisymmetric", "length": 6.0, "radius": R}, "mesh": {"nz": 12, "nr": 3, "order": 2},
           "time": {"end": 2e-4, "dt": 2e-4}, "fluid": "none",
           "layers": [{"model": "hgo-membrane", "density": RHO, "thickness": H, "c": HGO.c, "k1": HGO.k1,
                       "k2": HGO.k2, "angle": HGO.angle}],
           "initial": {"displacement": {"r": "0.075*sin(2*pi*z/L)"}}}


def one_step(data: dict, scheme: str):
    setup = Setup.build(validate_data(data, "/tmp", REGISTRY), REGISTRY)
    step = StructureStep(setup.stack, named(scheme), data["time"]["dt"], SolverStats())
    return step.step(setup.initial_state(), {}).newton


def test_newton_converges_quadratically_in_a_wall_step():
    """Backward Euler's step from a deflection of ±25 % of R (fibres on in one half, off in the other): each
    residual once near is at most the square of the one before."""
    residuals = one_step(RINGING, "backward-euler").residuals
    # measured: 1.0, 5.8e-02, 4.3e-04, 3.1e-08, 4.1e-16
    assert len(residuals) >= 5 and residuals[-1] <= 1e-13, residuals
    tail = residuals[-4:]
    assert all(b <= a * a for a, b in zip(tail, tail[1:])), residuals


def test_crank_nicolson_conserves_the_membranes_energy(tmp_path):
    """Undamped ringing of the HGO membrane alone under Crank–Nicolson's discrete gradient: W + kinetic kept to
    the Newton tolerance's size over 20 steps."""
    data = {**RINGING, "time": {"end": 4e-3, "dt": 2e-4}, "coupler": {"model": "structure-only",
                                                                          "scheme": "crank-nicolson"}}
    result = run_case(validate_data(data, tmp_path, REGISTRY), tmp_path / "run", REGISTRY)
    assert result.status == "ok", result.reason
    series = read_run("run", tmp_path / "run").series
    energy = series["energy.total"]
    assert np.max(np.abs(energy - energy[0])) <= 1e-10 * energy[0]  # measured 4.7e-12
    assert np.max(series["energy.relative_residual"]) <= 1e-9


# ---- coupled: the carotid-like artery with the membrane as its intima ----------------------------------------------


def carotid(layer: dict, coupler: dict, end: float = 0.01) -> dict:
    data = tomllib.loads(CAROTID.read_text())
    data["layers"][0] = layer
    data["mesh"].update(nz=12, nr=3)
    data["time"]["end"] = end
    data["coupler"] = coupler
    data["output"]["probes"] = [p for p in data["output"]["probes"] if p["name"] in ("eta_z3", "q_in", "p_mid")]
    return data


INTIMA = {"model": "neo-hookean-membrane", "density": 1.06, "thickness": 0.005, "c": 6.67e5}
HGO_INTIMA = {**RINGING["layers"][0], "thickness": 0.005}


@pytest.mark.parametrize("layer, scheme", [(INTIMA, "backward-euler"), (HGO_INTIMA, "crank-nicolson")],
                         ids=["neo-hookean-backward-euler", "hgo-crank-nicolson"])
def test_the_carotid_with_a_hyperelastic_intima_closes_its_ledger_monolithic(tmp_path, layer, scheme):
    data = carotid(layer, {"model": "monolithic", "scheme": scheme})
    result = run_case(validate_data(copy.deepcopy(data), CAROTID.parent, REGISTRY), tmp_path / "run", REGISTRY)
    assert result.status == "ok", result.reason
    run = read_run("run", tmp_path / "run")
    assert run.summary["energy"]["max_relative_residual"] <= 1e-9
    assert run.summary["newton"]["static"]["solves"] >= 1 and run.summary["newton"]["monolithic"]["solves"] == 10
    # the static start under 75 mmHg inflated the lumen: the membrane stretched around
    assert np.min(run.series["eta_z3"]) > 1e-3


def test_the_splitting_refuses_the_membrane_and_says_why(tmp_path):
    """Its impedance needs a linear wall; its paper's Robin term (which takes a nonlinear wall) loses a prescribed
    flow rate through the wall: both refusals name the reason and what to choose instead."""
    with pytest.raises(CaseError, match="layers\\[0\\] \\('neo-hookean-membrane'\\) is nonlinear.*'monolithic'"):
        validate_data(carotid(INTIMA, {"model": "kinematic-splitting"}), CAROTID.parent, REGISTRY)
    with pytest.raises(CaseError, match="loads.inlet prescribes a flow rate.*robin = 'inertia'"):
        validate_data(carotid(INTIMA, {"model": "kinematic-splitting", "robin": "inertia"}), CAROTID.parent, REGISTRY)


def test_the_splitting_with_the_inertia_runs_the_membrane_under_a_pressure_inlet(tmp_path):
    """The carotid with a pressure pulse in instead of the flow rate: the paper's scheme takes the nonlinear
    membrane (its structure step is a whole wall step, solved by Newton) and closes the ledger."""
    data = carotid(INTIMA, {"model": "kinematic-splitting", "robin": "inertia"})
    data["loads"]["inlet"] = {"model": "cosine-pulse", "amplitude": 1.3e4, "duration": 0.01}
    data["initial"] = {}
    data["solver"] = {"volume_margin": 1e9}  # the paper's Robin term loses volume through a stiff wall (theory §7)
    result = run_case(validate_data(data, CAROTID.parent, REGISTRY), tmp_path / "run", REGISTRY)
    assert result.status == "ok", result.reason
    run = read_run("run", tmp_path / "run")
    assert run.summary["energy"]["max_relative_residual"] <= 1e-9


# ---- the static start's bound ----------------------------------------------------------------------------------

#: the membrane alone lining a tube at rest under a uniform pressure (its largest, hc/R, is 1.11e4 dyn/cm²)
TUBE = {"geometry": {"model": "axisymmetric", "length": 6.0, "radius": R}, "mesh": {"nz": 12, "nr": 3, "order": 2},
        "time": {"end": 2e-3, "dt": 1e-3}, "fluid": {"model": "navier-stokes", "density": 1.06, "viscosity": 0.035},
        "layers": [INTIMA], "coupler": {"model": "monolithic"},
        "output": {"probes": [{"name": "eta_mid", "quantity": "eta", "z": 3.0}]}}


def test_a_membrane_alone_starts_beyond_the_linear_walls_small_strain(tmp_path):
    """8000 dyn/cm² inflates it by 0.374 R (λθ⁴ = 1/(1 − pR/(hc))): beyond the R/4 that validation asks of a
    linear wall, within the run's max_displacement; the run started there stays there."""
    P = 8000.0
    data = {**TUBE, "initial": {"pressure": P}, "loads": {"inlet": P, "outlet": P}}
    result = run_case(validate_data(data, tmp_path, REGISTRY), tmp_path / "run", REGISTRY)
    assert result.status == "ok", result.reason
    eta = read_run("run", tmp_path / "run").series["eta_mid"]
    exact = R * ((1 - P * R / (H * NEO.c)) ** -0.25 - 1)
    assert 0.25 * R < exact < 0.5 * R
    assert np.max(np.abs(eta - eta[0])) <= 1e-9 * exact  # measured 7.4e-14
    # measured 6.6e-7: the pinned ends' boundary layer (~0.13 cm wide) on cells of 0.5 cm
    assert abs(eta[0] / exact - 1) <= 1e-5


def test_validation_refuses_a_pressure_beyond_the_membranes_largest_and_says_why(tmp_path):
    with pytest.raises(CaseError, match="the wall cannot hold it: under it, on the lumen at rest, the wall moves it "
                                        "by .*a finite-strain wall holds no more than its largest pressure"):
        validate_data({**TUBE, "initial": {"pressure": 2.0e4}}, tmp_path, REGISTRY)
    # behind linear bands the small-strain bound stays
    with pytest.raises(CaseError, match="expected \\|η\\| ≤ 0.25 R = 0.075 cm \\(the linear wall's small strain\\)"):
        data = carotid(INTIMA, {"model": "monolithic"})
        data["initial"]["pressure"] = 2.0e5
        validate_data(data, CAROTID.parent, REGISTRY)
