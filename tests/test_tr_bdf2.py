"""TR-BDF2 (``multilayer_plugins/schemes/tr_bdf2.py``): a multi-stage scheme stepped stage by stage by the clock.

Its stages' identities chain over a step at any step ratio, its matrices are one, its local error constant is
the one its estimate uses, it is L-stable (an undamped stiff mode is gone after a step, where Crank–Nicolson
carries it), its ledger closes under every coupler that takes it, a resumed run writes the same bytes, and
adaptive steps close the ledger at every step.  Its orders: tests/test_fluid_womersley.py (the fluid alone) and
tests/test_coupled.py (the coupled pulse).
"""

import math

import numpy as np
import pytest
from runs import assert_resume_is_bit_identical, run_case_file, run_cli

from multilayer.numerics.timescheme import named
from multilayer_plugins.schemes.tr_bdf2 import GAMMA, LOCAL_ERROR

TR_BDF2 = named("tr-bdf2")


def amplification(scheme, z: complex) -> complex:
    """x^{n+1}/xⁿ of one step of ``scheme`` on x' = λx, z = λΔt (Δt = 1), its stages solved as the couplers solve
    them: for the test-level unknown x̄, (α₀/β₀) x̄ + h = Δt_s λ x̄, then x^{n+1} from x̄."""
    x = [1.0 + 0j]  # the chain, newest first: the step's stages' values, then xⁿ
    for stage, _, _, step in scheme.substeps(0.0, 1.0):
        old = (x + [x[-1]] * stage.levels)[: stage.levels - 1]
        xbar = -stage.history(old) / (stage.inertia - z * step)
        x.insert(0, stage.new_level(xbar, old))
    return x[0]


@pytest.mark.parametrize("ratio", [1.0, 1.7, 0.4])
def test_the_stages_chain_their_identities_and_share_one_matrix(ratio):
    """Over a step (its stages tested each with its own x̄) Σ_s (Σα x)·M x̄_s = q(x^{n+1}) − q(xⁿ) + N₁ + N₂ on random
    vectors, the trapezoidal stage storing what the BDF2 stage starts from; both stages' matrices
    (α₀/β₀)M/Δt_s + C + (β₀Δt_s/α₀)K have the same coefficients; the stage ends at tⁿ + γΔt."""
    S = TR_BDF2.with_ratio(ratio)
    (tr, t0, tg, _), (bdf, _, t1, _) = S.substeps(0.3, 0.5)
    assert math.isclose(tg, 0.3 + GAMMA * 0.2) and t1 == 0.5 and tr.ratio == pytest.approx(GAMMA * ratio)
    assert math.isclose(tr.inertia / (tg - t0), bdf.inertia / (t1 - tg), rel_tol=1e-14)
    assert math.isclose(tr.displacement_gain(tg - t0), bdf.displacement_gain(t1 - tg), rel_tol=1e-14)
    M = np.diag([2.0, 3.0, 0.5])
    q = lambda x: 0.5 * x @ M @ x  # noqa: E731
    rng = np.random.default_rng(7)
    for _ in range(5):
        x0, xg, x1 = (rng.normal(size=3) for _ in range(3))
        first = tr.difference([xg, x0]) @ M @ tr.average([xg, x0])
        second = bdf.difference([x1, xg, x0]) @ M @ bdf.average([x1, xg, x0])
        assert abs(first - (tr.stored(q, [xg, x0]) - q(x0) + tr.numerical(q, [xg, x0]))) < 1e-12
        assert abs(second - (bdf.stored(q, [x1, xg, x0]) - bdf.before(q, [x1, xg, x0])
                             + bdf.numerical(q, [x1, xg, x0]))) < 1e-12
        assert bdf.before(q, [x1, xg, x0]) == tr.stored(q, [xg, x0]) and S.stored(q, [x1, x0]) == q(x1)


def test_its_local_error_constant_is_the_one_its_estimate_uses():
    """(R(z) − eᶻ)/z³ → C = (3γ² − 4γ + 2)/(12(2 − γ)) as z → 0: the local error C Δt³ x''' on x' = λx (x''' = λ³x),
    the constant of its Milne factor; Crank–Nicolson's 1/12 the same way."""
    for z in (1e-3, -1e-3, 1e-3j):
        assert abs((amplification(TR_BDF2, z) - np.exp(z)) / z**3 - LOCAL_ERROR) < 2e-3 * LOCAL_ERROR
        assert abs((amplification(named("crank-nicolson"), z) - np.exp(z)) / z**3 - 1 / 12) < 2e-3 / 12
    assert LOCAL_ERROR == pytest.approx(0.04044, abs=1e-5)


def test_it_is_l_stable():
    """A-stable (|R(z)| ≤ 1 on the left half-plane, sampled) and |R(z)| → 0 as z → ∞ there: R(−10⁶) and R(10⁶ i)
    are O(1/|z|), where Crank–Nicolson's stay at |R| = 1."""
    for z in [-x for x in np.logspace(-3, 8, 45)] + [1j * y for y in np.logspace(-3, 8, 45)] + [
            r * np.exp(1j * a) for r in (0.5, 5.0, 50.0) for a in np.linspace(np.pi / 2, 3 * np.pi / 2, 13)]:
        assert abs(amplification(TR_BDF2, z)) <= 1.0 + 1e-14, z
    for z in (-1e6, 1e6j, -1e6 + 1e6j):
        assert abs(amplification(TR_BDF2, z)) < 10.0 / abs(z)
        assert abs(abs(amplification(named("crank-nicolson"), z)) - 1.0) < 1e-5


def test_a_stiff_wall_mode_is_gone_after_a_step_and_its_energy_is_in_the_ledger(tmp_path):
    """The membrane's mode 1 made 10⁸ times stiffer (ω₁Δt ≈ 2 200 at Δt = 1e-3), free from η = 0.01 sin(πz/L):
    TR-BDF2 leaves less than 1e-3 of it after one step (the amplification R(2 200 i) ~ 1/ω₁Δt) and the ledger
    puts the energy it took in the numerical dissipation (closing to round-off); Crank–Nicolson carries the mode
    undamped, |η| = 0.01 alternating, its energy conserved."""
    sets = ("layers[0].tension=2.0e12", "time.dt=1e-3", "time.end=0.005")
    out = {}
    for scheme in ("tr-bdf2", "crank-nicolson"):
        result, data = run_case_file("membrane-mode", tmp_path / scheme, f'coupler.scheme="{scheme}"', *sets)
        assert result.status == "ok" and result.max_relative_residual < 1e-10
        out[scheme] = {k: np.asarray(v, dtype=float) for k, v in data.series.items()}
    tr, cn = out["tr-bdf2"], out["crank-nicolson"]
    assert np.all(np.abs(tr["eta_mid"]) < 1e-3 * 0.01)
    assert np.allclose(np.abs(cn["eta_mid"]), 0.01, rtol=1e-3) and np.all(np.diff(np.sign(cn["eta_mid"])) != 0)
    initial = cn["energy.total"][0]
    assert tr["energy.total"][-1] < 1e-5 * initial
    assert tr["dissipation.numerical.wall"][0] == pytest.approx(initial, rel=1e-4)


#: every coupler that steps TR-BDF2, on a case it runs (the paper's splitting and Dirichlet–Neumann refuse it:
#: tests/test_timescheme.py)
LEDGER = {
    "monolithic": ("pulse-koiter-thick", "mesh.nz=12", "mesh.nr=3", "time.end=0.002"),
    "monolithic-band": ("thick-wall", "mesh.nz=12", "mesh.nr=3", "time.end=0.002"),
    "monolithic-tube": ("pulse-koiter-thick-axisymmetric", "mesh.nz=12", "mesh.nr=3", "time.end=0.002",
                        "coupler.model=monolithic"),
    "kinematic-splitting": ("pulse-koiter-thick", "mesh.nz=12", "mesh.nr=3", "time.end=0.002",
                            "coupler.model=kinematic-splitting"),
    "kinematic-splitting-tube": ("pulse-koiter-thick-axisymmetric", "mesh.nz=12", "mesh.nr=3", "time.end=0.002",
                                 "coupler.model=kinematic-splitting"),
    "structure-only": ("membrane-mode", "time.end=0.004"),
    "fluid-only": ("womersley-rigid", "time.end=0.2"),
}


@pytest.mark.parametrize("coupler", LEDGER)
def test_the_ledger_closes_every_step_under_every_coupler_that_takes_it(coupler, tmp_path):
    """The step's row: the last stage's stored energy, the stages' work and dissipation summed; it closes to
    round-off every step (measured ≤ 1e-12), and the lumen's volume stage by stage (in a planar channel to
    round-off)."""
    case, *sets = LEDGER[coupler]
    if "coupler.model" not in " ".join(sets):
        sets.append(f"coupler.model={coupler.removesuffix('-band')}")
    code, summary, rows = run_cli(case, tmp_path / coupler, *sets, 'coupler.scheme="tr-bdf2"')
    assert code == 0 and summary["status"] == "ok", summary["reason"]
    assert summary["scheme"] == {"name": "tr-bdf2", "order": 2} and len(rows) == summary["steps"]
    residuals = np.array([float(r["energy.relative_residual"]) for r in rows])
    assert np.all(residuals <= 1e-9), residuals.max()
    if "volume" in summary and summary["case"]["geometry"]["model"] == "planar" and not coupler.endswith("-band"):
        # (a band at the fluid moves the domain axially too, under no-slip: its volume is not round-off under any
        # scheme, measured 1.6e-5 Crank–Nicolson, 8.3e-5 BDF2, 8.6e-6 TR-BDF2 a step on the band case here)
        assert summary["volume"]["max_relative_residual"] <= 1e-9, summary["volume"]


def test_a_resumed_run_writes_the_same_bytes(tmp_path):
    """The step's state carries the step's old levels only (the stages' values belong to the step), so a
    checkpoint holds what a run needs: adaptive monolithic TR-BDF2 resumed at half way, bit for bit."""
    assert_resume_is_bit_identical(tmp_path, "pulse-koiter", "geometry.length=2.0", "mesh.nz=8", "mesh.nr=2",
                                   'output.probes=[{ name = "eta_z1", quantity = "eta", z = 1.0 }]',
                                   'coupler={model="monolithic",scheme="tr-bdf2"}', "time.dt=1e-5",
                                   "time.tolerance=1e-3", "time.output_interval=1e-3", every=7)


@pytest.mark.parametrize("coupler", ["monolithic", "kinematic-splitting"])
def test_adaptive_steps_close_the_ledger_at_every_step(coupler, tmp_path):
    """The composite pulse (12 × 3 cells, 2 ms) from a first step of 1e-6 s, tolerance 1e-3: the steps change, the
    ledger closes at every step, the steps never collapse (the smallest is the start's)."""
    code, summary, rows = run_cli("pulse-koiter-thick", tmp_path / coupler, "mesh.nz=12", "mesh.nr=3",
                                  "time.end=0.002", "time.dt=1e-6", "time.tolerance=1e-3",
                                  f'coupler={{model="{coupler}",scheme="tr-bdf2"}}')
    assert code == 0 and summary["status"] == "ok", summary["reason"]
    dt = np.array([float(r["dt"]) for r in rows])
    assert summary["adaptive"]["accepted"] == len(rows) and len(set(dt)) > 10
    assert np.all(np.array([float(r["energy.relative_residual"]) for r in rows]) <= 1e-9)
    assert dt.min() >= 1e-7 and float(rows[-1]["t"]) == 0.002
