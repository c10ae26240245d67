"""The fluid-only cases run as they are and match what the physics fixes.

Each case runs through the command line on a coarse mesh (``--set``); the
checks read ``summary.json``, ``series.csv`` and the fluid snapshots, as a
user of the results folder would.
"""


import meshio
import numpy as np
import pytest
from runs import run_cli

from multilayer.numerics.linsolve import BACKENDS

MU, RHO = 0.035, 1.0


def run(case, out, *sets):
    code, summary, rows = run_cli(case, out, *sets)
    return code, summary, [{k: float(v) for k, v in r.items()} for r in rows]


def column(rows, name):
    return np.array([r[name] for r in rows])


# -- Poiseuille ---------------------------------------------------------------
# ΔP = 10, L = 6, R = 0.5 (poiseuille-rigid.toml). From rest, the slowest
# transient of the planar channel (no slip at R, symmetry at 0) decays like
# exp(−λ₁t), λ₁ = (μ/ρ)(π/(2R))²; its share of the axis velocity is 32/π³.
# Backward Euler damps it by 1/(1 + λ₁Δt) per step, and the discrete λ₁ of the
# constrained Galerkin problem is not below the continuous one, so after N
# steps the axis velocity is within (32/π³)(1 + λ₁Δt)^−N of the parabola.
# P2/P1 holds the parabola and the linear pressure exactly.
POISEUILLE = dict(dp=10.0, L=6.0, R=0.5, dt=4.0, steps=20)


def test_poiseuille_reaches_the_parabola_and_factorizes_once(tmp_path):
    c = POISEUILLE
    code, summary, rows = run("poiseuille-rigid", tmp_path / "p", "mesh.nz=6", "mesh.nr=2",
                              f"time.dt={c['dt']}", f"time.end={c['dt'] * c['steps']}", "output.every=0")
    assert code == 0 and summary["status"] == "ok"
    assert summary["energy"]["max_relative_residual"] <= 1e-10
    assert summary["factorizations"]["fluid"] == 1  # Stokes, rigid wall, fixed Δt: one constant matrix
    lam1 = MU / RHO * (np.pi / (2 * c["R"])) ** 2
    transient = 32 / np.pi**3 * (1 + lam1 * c["dt"]) ** -c["steps"]  # ≈ 3e-8
    u_axis = c["dp"] * c["R"] ** 2 / (2 * MU * c["L"])
    q = c["dp"] * c["R"] ** 3 / (3 * MU * c["L"])
    last = rows[-1]
    assert abs(last["uz_axis"] - u_axis) / u_axis <= 2 * transient
    assert abs(last["uz_axis"] - u_axis) / u_axis > 1e-12  # still approaching: the bound is the one in play
    for name in ("q_in", "q_out"):
        assert abs(last[name] - q) / q <= 2 * transient
    assert abs(last["p_mid"] - c["dp"] / 2) <= 1e-9 * c["dp"]
    # rigid wall, incompressible: what enters leaves, every step
    assert np.max(np.abs(column(rows, "q_in") - column(rows, "q_out"))) <= 1e-12 * q


# -- Womersley ----------------------------------------------------------------
def test_womersley_runs_with_a_closed_ledger_and_one_factorization(tmp_path):
    code, summary, rows = run("womersley-rigid", tmp_path / "w", "mesh.nz=4", "mesh.nr=6",
                              "time.dt=0.02", "time.end=1.0", "output.every=0")
    assert code == 0 and summary["status"] == "ok" and summary["steps"] == 50
    assert summary["energy"]["max_relative_residual"] <= 1e-10
    assert summary["factorizations"]["fluid"] == 1
    q_in, q_out = column(rows, "q_in"), column(rows, "q_out")
    assert np.max(np.abs(q_in - q_out)) <= 1e-12 * np.max(np.abs(q_in))
    # the flow follows the sine drop with a lag: it reverses within the period
    assert q_in.max() > 0 > q_in.min()


# -- Prescribed wall ----------------------------------------------------------
# prescribed-wall.toml: η = a sin(πz/L) sin(2πt/T₀), a = 0.05, L = 2, R = 0.5, T₀ = 0.1
WALL = dict(a=0.05, L=2.0, R=0.5, T0=0.1, nz=8, dt=0.005, every=2)


def area(t):
    """∫₀ᴸ (R + η(t, z)) dz from the case's formula."""
    w = WALL
    return w["R"] * w["L"] + w["a"] * 2 * w["L"] / np.pi * np.sin(2 * np.pi * t / w["T0"])


@pytest.fixture(scope="module")
def prescribed(tmp_path_factory):
    w = WALL
    out = tmp_path_factory.mktemp("prescribed")
    code, summary, rows = run("prescribed-wall", out, f"mesh.nz={w['nz']}", "mesh.nr=3",
                              f"time.dt={w['dt']}", f"output.every={w['every']}")
    return out, code, summary, rows


def test_prescribed_wall_mass_balance(prescribed):
    out, code, summary, rows = prescribed
    w = WALL
    assert code == 0 and summary["status"] == "ok" and summary["steps"] == 20
    assert summary["energy"]["max_relative_residual"] <= 1e-10
    # the domain moves: a new matrix every step, factorized or solved by GMRES on an earlier factorization
    assert summary["factorizations"]["fluid"] + summary["krylov"]["fluid"]["solves"] == summary["steps"]
    t = column(rows, "t")
    rate = (area(t) - area(t - w["dt"])) / w["dt"]
    # The scheme conserves the area of the P2 interpolant of η exactly; its
    # integral is Simpson's rule on each cell, whose error relative to
    # max dA/dt is at most π⁵/(5760 nz⁴) ≈ 1.3e-5 for sin(πz/L) on nz cells.
    scale = w["a"] * 2 * w["L"] / np.pi * 2 * np.pi / w["T0"]
    simpson = np.pi**5 / (5760 * w["nz"] ** 4)
    misfit = np.max(np.abs(column(rows, "q_in") - column(rows, "q_out") - rate)) / scale
    assert misfit <= simpson + 1e-12
    assert np.max(np.abs(column(rows, "q_in") - column(rows, "q_out"))) > 0.5 * scale  # the wall does pump


def test_fluid_snapshots_are_readable_and_deformed(prescribed):
    out, code, summary, rows = prescribed
    w = WALL
    assert (out / "fluid.pvd").is_file()
    steps = {int(f.stem.split("_")[1]) for f in out.glob("fluid_*.vtu")}
    assert set(range(0, summary["steps"] + 1, w["every"])) <= steps  # t = 0 included
    step = w["every"]  # t = 0.01: η(L/2) = a sin(2π/10) > 0
    m = meshio.read(out / f"fluid_{step:06d}.vtu")
    eta_mid = w["a"] * np.sin(2 * np.pi * step * w["dt"] / w["T0"])
    assert abs(m.points[:, 1].max() - (w["R"] + eta_mid)) <= 1e-12
    assert set(m.point_data) == {"velocity", "pressure"}  # in place already: no displacement to warp twice
    half = meshio.read(out / "fluid_000010.vtu")  # t = T₀/2: η = 0 again
    assert abs(half.points[:, 1].max() - w["R"]) <= 1e-12


# -- the optional fast solver -------------------------------------------------
@pytest.mark.skipif("pardiso" not in BACKENDS, reason="optional extra 'fast' (pypardiso) not installed")
def test_pardiso_gives_the_superlu_solution(tmp_path):
    sets = ("mesh.nz=8", "mesh.nr=3", "time.dt=0.005", "time.end=0.03", "output.every=0")
    _, _, ref = run("prescribed-wall", tmp_path / "superlu", *sets)
    code, summary, rows = run("prescribed-wall", tmp_path / "pardiso", *sets, "solver.linear=pardiso")
    assert code == 0 and summary["status"] == "ok"
    assert summary["energy"]["max_relative_residual"] <= 1e-10
    for name in ("q_in", "q_out", "p_mid", "uz_axis"):
        a, b = column(ref, name), column(rows, name)
        assert np.max(np.abs(a - b)) <= 1e-10 * np.max(np.abs(a))



@pytest.mark.skipif("pardiso" not in BACKENDS, reason="optional extra 'fast' (pypardiso) not installed")
def test_pardiso_has_no_single_precision_factors(tmp_path, capsys):
    from runs import CASES

    from multilayer.commands.main import main

    code = main(["run", str(CASES / "prescribed-wall.toml"), "--out", str(tmp_path), "--quiet",
                 "--set", "solver.linear=pardiso", "--set", "solver.factors=single"])
    err = capsys.readouterr().err
    assert code != 0 and "solver.factors = 'single'" in err and "need linear = one of ['superlu'" in err
