"""The wall shear stress τ_w = −t·2μD(u)n on the lumen (multilayer_plugins.channel.wall_shear, docs/readouts.md).

Against exact solutions, in the planar channel (a half-channel of half-height R over its symmetry line, Q per
unit depth through the half) and the tube:

* Poiseuille: τ_w = −μ ∂_r u_z(R) = G R = 3μQ/R² (planar), G R/2 = 4μQ/(πR³) (tube), G = ΔP/L; Taylor–Hood
  holds the parabola, so its τ_w is exact to round-off, at every lumen DOF;
* a velocity of constant gradient A on a wall tilted by η' (a linear η), and on a domain also moved axially
  (d_z quadratic): P2 holds both, τ_w = −μ t·(A + Aᵀ)n with t ∝ F e_ẑ = (1 + d_z', η'), to round-off;
* Womersley flow (the profile's slope at the wall, against backward Euler's own exact periodic solution to
  isolate the space error; tests/test_fluid_womersley.py): the gradient's order, 2 for P2 and 1 for P1b.
  Measured (nz = 2; nr = 8, 16, 32, 64, 128; max over the lumen, relative to |τ_w|):

      P2  planar 2.94e-3 1.72e-3 6.25e-4 1.83e-4 4.95e-5   orders 0.77 1.46 1.77 1.89
          tube   7.38e-3 3.14e-3 9.86e-4 2.74e-4 7.22e-5   orders 1.23 1.67 1.85 1.93
      P1b planar 2.26e-1 1.13e-1 5.50e-2 2.69e-2 1.32e-2   orders 1.00 1.03 1.03 1.02
          tube   1.93e-1 9.27e-2 4.43e-2 2.14e-2 1.04e-2   orders 1.05 1.07 1.05 1.03

  (the Stokes layer, 0.11 cm at Womersley number 6.7, is resolved from nr ≈ 16 on).

And a run writes it: ``wss_lumen.csv`` every step at the lumen's vertices, ``lumen_*.vtu`` with ``wss``.
"""

import json

import meshio
import numpy as np
import pytest
from fluid_steps import fluid_step, setup_fluid
from runs import run_case_file
from scipy.special import jv
from test_axisymmetric_fluid import womersley_pipe
from test_fluid_womersley import MU, OMEGA, PERIOD, RHO, R, march, orders, womersley

from multilayer.results.reading import position_column
from multilayer_plugins.axisymmetric import Axisymmetric
from multilayer_plugins.channel import Stokes
from multilayer_plugins.channel.channel import Channel
from multilayer_plugins.channel.extension import AxialExtension
from multilayer_plugins.channel.wall_shear import WallShear
from multilayer_plugins.planar import Planar

GEOMETRIES = {"planar": Planar(), "axisymmetric": Axisymmetric()}


@pytest.mark.parametrize("kind", GEOMETRIES)
def test_poiseuille_wall_shear_is_exact_to_round_off(kind):
    geometry, length, dp = GEOMETRIES[kind], 6.0, 10.0
    fluid = Stokes(RHO, MU)
    setup_fluid(fluid, length, R, nz=6, nr=4, order=2, wall="rigid", geometry=geometry)
    state = fluid.initial_state()
    for _ in range(12):  # Δt = 1000 s: the start-up transient is gone, (1 + λ₁Δt)^-12 < 1e-30
        state, _ = fluid_step(fluid, state, 1e3, p_in=dp, p_out=0.0)
    tau = fluid.wall_shear(state)
    q = fluid.flow_rate(state, None, 0.5 * length)
    G = dp / length
    if kind == "planar":
        assert np.allclose(tau, 3 * MU * q / R**2, rtol=1e-12, atol=0), tau
        assert np.allclose(tau, G * R, rtol=1e-11, atol=0)
    else:
        assert np.allclose(tau, 4 * MU * q / (np.pi * R**3), rtol=1e-12, atol=0), tau
        assert np.allclose(tau, G * R / 2, rtol=1e-11, atol=0)


A = np.array([[0.3, -1.7], [0.9, 0.4]])  # ∂_j u_i, constant


def expected(tangent):
    t = np.asarray(tangent) / np.linalg.norm(tangent, axis=0)
    n = np.array([-t[1], t[0]])
    return -MU * np.einsum("ik,ij,jk->k", t, A + A.T, n)


@pytest.mark.parametrize("kind", GEOMETRIES)
def test_a_tilted_wall_takes_its_own_tangent_and_normal(kind):
    """η = a + b z: the physical field A x is quadratic on the reference channel, held by P2."""
    ch = Channel.build(GEOMETRIES[kind], 2.0, R, nz=6, nr=3, order=2)
    a, b = 0.03, 0.02
    eta = a + b * ch.line.z
    u = ch.interpolate(lambda zh, rh: tuple(A @ np.array([zh, rh * (R + a + b * zh) / R])))
    tau = WallShear(ch, MU)(u, eta)
    assert np.allclose(tau, expected(np.array([[1.0], [b]])), rtol=1e-13, atol=0)
    flat = expected(np.array([[1.0], [0.0]]))
    assert np.all(np.abs(tau - flat) > 1e-3 * np.abs(flat))  # the tilt matters: 0.6 % here


@pytest.mark.parametrize("kind", GEOMETRIES)
def test_an_axially_moved_wall_takes_the_maps_tangent(kind):
    """No-slip at a thick band: the domain also moves by D_z, the harmonic extension of d_z = ε z(L − z)."""
    length, eps, a, b = 2.0, 0.01, 0.03, 0.02
    ch = Channel.build(GEOMETRIES[kind], length, R, nz=6, nr=3, order=2)
    extension = AxialExtension(ch)
    d_z = eps * ch.line.z * (length - ch.line.z)
    eta = a + b * ch.line.z
    D = extension.extend(d_z)
    zh, rh = ch.velocity.doflocs
    x = np.vstack([zh + extension.basis.probes(ch.velocity.doflocs) @ D, rh * (R + a + b * zh) / R])
    u = np.einsum("ij,jk->ik", A, x)
    comp_z, comp_r = ch.velocity.split_indices()
    values = np.zeros(ch.nu)
    values[comp_z], values[comp_r] = u[0, comp_z], u[1, comp_r]
    tau = WallShear(ch, MU)(values, eta, (extension, d_z))
    z = ch.line.z
    assert np.allclose(tau, expected(np.vstack([1.0 + eps * (length - 2 * z), np.full_like(z, b)])),
                       rtol=1e-12, atol=0)


def exact_wall_shear(kind, G, lam, t):
    """τ_w = −μ ∂_r u_z(R) of the Womersley profile G/(iωρ) (1 − f(κr)/f(κR)) e^{iωt}, f = cosh or J₀(i·)."""
    kappa = np.sqrt(RHO * lam / MU)
    amplitude = G / (1j * OMEGA * RHO)
    if kind == "planar":
        slope = -amplitude * kappa * np.tanh(kappa * R)
    else:
        slope = amplitude * 1j * kappa * jv(1, 1j * kappa * R) / jv(0, 1j * kappa * R)
    return np.real(-MU * slope * np.exp(1j * OMEGA * t))


def womersley_error(kind, order, nr, G=10.0, dt=PERIOD / 20, steps=4):
    lam = (1 - np.exp(-1j * OMEGA * dt)) / dt  # backward Euler's symbol: its own exact periodic solution
    exact = womersley(G, lam) if kind == "planar" else womersley_pipe(G, lam)
    fluid = Stokes(RHO, MU)
    setup_fluid(fluid, 1.0, R, nz=2, nr=nr, order=order, wall="rigid", geometry=GEOMETRIES[kind])
    state, t = march(fluid, exact, G, dt, steps, "backward-euler")
    tau = exact_wall_shear(kind, G, lam, t)
    return np.max(np.abs(fluid.wall_shear(state) - tau)) / abs(tau)


@pytest.mark.parametrize("kind", GEOMETRIES)
@pytest.mark.parametrize("order, expected_order, meshes, first", [(2, 2.0, (32, 64, 128), 1.5e-3),
                                                                  (1, 1.0, (16, 32, 64), 0.15)])
def test_womersley_wall_shear_converges_at_the_gradients_order(kind, order, expected_order, meshes, first):
    errors = [womersley_error(kind, order, nr) for nr in meshes]
    assert errors[0] < first  # measured P2 6.25e-4 (planar), 9.86e-4 (tube); P1b 0.113, 0.093
    assert np.all(np.abs(orders(errors) - expected_order) < 0.25), orders(errors)


@pytest.mark.parametrize("kind", GEOMETRIES)
def test_a_run_writes_the_wall_shear_stress_every_step_and_in_its_snapshots(tmp_path, kind):
    """The bundled rigid Poiseuille case (in the planar channel and as a tube): ``wss_lumen.csv`` at the lumen's
    vertices, headers without float noise, its last row 3μQ/R² (4μQ/(πR³)) of the run's own outflow."""
    result, data = run_case_file("poiseuille-rigid", tmp_path, f"geometry.model={kind}")
    assert result.status == "ok", result.reason
    header = (tmp_path / "wss_lumen.csv").read_text().splitlines()[0].split(",")
    z = np.linspace(0.0, 6.0, 25)
    assert header == ["step", "t", *(position_column(v) for v in z)]
    assert "z=0.75" in header and not any("0000" in c for c in header)
    rows = np.loadtxt(tmp_path / "wss_lumen.csv", delimiter=",", skiprows=1)
    assert rows.shape == (30, 2 + 25)
    q = data.series["q_out"][-1]
    tau = 3 * MU * q / R**2 if kind == "planar" else 4 * MU * q / (np.pi * R**3)
    assert np.allclose(rows[-1, 2:], tau, rtol=1e-6, atol=0)  # the run is steady to ~1.5e-7
    pvd = (tmp_path / "lumen.pvd").read_text()
    assert pvd.count("<DataSet") == 4  # every 10 steps, and t = 0
    snapshot = meshio.read(tmp_path / "lumen_000030.vtu")
    assert np.allclose(snapshot.points[:, 1], R) and np.allclose(np.sort(snapshot.points[:, 0]), z)
    assert np.allclose(snapshot.point_data["wss"], tau, rtol=1e-6)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["wss"]["z"] == pytest.approx(z) and "cycles" not in summary  # a constant load has no cycles


def test_a_run_resumed_into_tables_with_unrounded_headers_keeps_them(tmp_path):
    """A lumen table begun by a multilayer that wrote z=0.6000000000000001 is resumed as it was written."""
    from runs import CASES

    from multilayer.commands.main import main

    sets = ["--set", "mesh.nz=12", "--set", "mesh.nr=3"]
    out = tmp_path / "run"
    assert main(["run", str(CASES / "pulse-koiter-thick.toml"), "--out", str(out), "--quiet", "--no-plots",
                 "--checkpoint-every", "10", *sets, "--set", "time.end=0.002"]) == 0
    for name in ("eta_lumen.csv", "wss_lumen.csv"):
        path = out / name
        lines = path.read_text().split("\n")
        header = lines[0].split(",")
        noisy = header[:2] + [f"z={float(np.nextafter(float(c[2:]), np.inf)) if float(c[2:]) else 0.0!r}"
                              for c in header[2:]]
        assert any(len(c) > 12 for c in noisy)
        path.write_text("\n".join([",".join(noisy), *lines[1:]]))
    assert main(["resume", str(out), "--until", "0.004", "--quiet", "--no-plots"]) == 0
    for name in ("eta_lumen.csv", "wss_lumen.csv"):
        rows = (out / name).read_text().splitlines()
        assert len(rows) == 1 + 40 and len(rows[0].split(",")[5]) > 12, name
