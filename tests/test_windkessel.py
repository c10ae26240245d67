"""Resistance and RCR Windkessel ends: the 0D model exact where it must be, its order, its ledger, its stability.

A rigid channel in steady Stokes flow is a linear resistance R_ch = 3μL/R³
(per unit depth, half channel 0 < r < R).  Driven by a constant inlet
pressure P_in into an RCR outlet it is a 0D circuit: the capacitor's
pressure relaxes to P_∞ = (P_in R_d + P_d (R_ch + R_p))/(R_ch + R_p + R_d)
with the time constant τ = C (R_ch + R_p) R_d/(R_ch + R_p + R_d), once the
channel's own viscous transient (time ~ ρR²/μ) has died out.  P2/P1 holds
the steady parabola, so the steady state is exact to round-off; the
transient differs from the 0D exponential by the time scheme's error and by
the fluid's inertia (a lag of order ρR²/(μτ) of the relaxation).
"""

import math

import numpy as np
import pytest
from runs import CASES, assert_resume_is_bit_identical, run_case_file

from multilayer.case.casefile import load_case
from multilayer.numerics.timescheme import named, schemes
from multilayer.plugin.problems import CaseError
from multilayer_plugins.windkessel import CapacitorState, Windkessel

L, P_IN = 6.0, 10.0


def run(tmp_path, case, *sets):
    return run_case_file(case, tmp_path, *sets)


def rcr(proximal, capacitance, distal, distal_pressure=0.0):
    return (f'loads.outlet={{model="windkessel",proximal={proximal},capacitance={capacitance},distal={distal},'
            f'distal_pressure={distal_pressure}}}')


def test_steady_flow_through_an_rcr_outlet_is_exact(tmp_path):
    R, mu = 0.5, 0.035
    channel = 3.0 * mu * L / R**3
    Rp, C, Rd, Pd = 20.0, 0.05, 60.0, 2.0
    # Δt = 1000 s: backward Euler damps the channel's transient (0.345/s) and the circuit's (τ ≈ 1.3 s) by
    # ~1e-3 a step, so 20 steps leave round-off
    result, data = run(tmp_path, "poiseuille-rigid", "time.dt=1000.0", "time.end=20000.0", rcr(Rp, C, Rd, Pd))
    assert result.status == "ok"
    s = data.series
    q = (P_IN - Pd) / (channel + Rp + Rd)
    assert s["end.outlet.Q"][-1] == pytest.approx(q, rel=1e-11)
    assert -s["end.inlet.Q"][-1] == pytest.approx(q, rel=1e-11) and s["q_out"][-1] == pytest.approx(q, rel=1e-11)
    assert s["end.outlet.P_c"][-1] == pytest.approx(Pd + Rd * q, rel=1e-11)
    assert s["end.outlet.p"][-1] == pytest.approx(Pd + (Rp + Rd) * q, rel=1e-11)
    assert np.all(s["energy.relative_residual"] <= 1e-11)


def relaxation(scheme, dt, tmp_path):
    """The capacitor's pressure after τ in a viscous narrow channel (ρR²/μ = 0.0625 s against τ = 60 s)."""
    R, mu = 0.25, 1.0
    channel = 3.0 * mu * L / R**3  # 1152
    Rp, C, Rd, Pd = 48.0, 0.1, 1200.0, 2.0
    tau = C * (channel + Rp) * Rd / (channel + Rp + Rd)  # 60 s
    p_inf = (P_IN * Rd + Pd * (channel + Rp)) / (channel + Rp + Rd)
    result, data = run(tmp_path / f"{scheme}-{dt}", "poiseuille-rigid", f"geometry.radius={R}",
                       f"fluid.viscosity={mu}", "mesh.nz=8", "mesh.nr=4", f"time.dt={dt}", f"time.end={tau}",
                       rcr(Rp, C, Rd, Pd), f'coupler={{model="fluid-only",scheme="{scheme}"}}', "output.probes=[]")
    assert result.status == "ok" and np.all(data.series["energy.relative_residual"] <= 1e-11)
    exact = p_inf + (Pd - p_inf) * math.exp(-1.0)
    return abs(data.series["end.outlet.P_c"][-1] - exact) / p_inf


def test_the_outlet_relaxes_with_the_0d_time_constant(tmp_path):
    """Measured (P_c at t = τ against the 0D exponential, relative to P_∞): backward Euler at Δt = 6, 3, 1.5,
    0.75 s: 1.18e-2, 6.06e-3, 3.09e-3, 1.58e-3 (order 1.0); Crank–Nicolson 5e-4–2e-4 at every Δt from 6 to
    0.375 s: it sits on the floor of the fluid's inertia (ρR²/(μτ) ≈ 1e-3), which the 0D model leaves out."""
    be = [relaxation("backward-euler", dt, tmp_path) for dt in (6.0, 3.0, 1.5)]
    orders = np.log2(np.array(be[:-1]) / np.array(be[1:]))
    assert np.all(np.abs(orders - 1.0) < 0.1), (be, orders)
    assert be[-1] < 4e-3
    assert relaxation("crank-nicolson", 3.0, tmp_path) < 1e-3


@pytest.mark.parametrize("scheme", sorted(schemes()))
def test_the_capacitor_is_integrated_at_the_scheme_order(scheme):
    """The Windkessel alone, driven by Q = Q₀ sin ωt: C P' = Q − (P − P_d)/R_d, exact solution below; every
    registered scheme at its order.

    Measured errors at t = 1 for Δt = 1/20 ... 1/160 (C = 0.5, R_d = 2, ω = 2π): backward Euler order
    1.0, Crank–Nicolson and BDF2 (started from the exact P(−Δt)) 2.0, TR-BDF2 (its stages one after the
    other, each from the levels before it) 2.0."""
    S = named(scheme)
    order = S.order
    C, Rd, Pd, Q0, w = 0.5, 2.0, 1.0, 3.0, 2.0 * math.pi
    a, b = 1.0 / (Rd * C), Q0 / C

    def exact(t):
        return Pd + b * (a * math.sin(w * t) - w * math.cos(w * t) + w * math.exp(-a * t)) / (a * a + w * w)

    def flux(t):
        return Q0 * math.sin(w * t)

    errors = []
    for n in (20, 40, 80, 160):
        dt = 1.0 / n
        wk = Windkessel(proximal=0.0, capacitance=C, distal=Rd, distal_pressure=Pd)
        history = [CapacitorState(exact(0.0), 0.0), CapacitorState(exact(-dt), 0.0)]
        for k in range(n):
            chain, times = list(history), [k * dt, (k - 1) * dt]  # newest first: the step's stages, then its levels
            for stage, t0, t1, h in S.substeps(k * dt, (k + 1) * dt, dt):
                old = chain[:stage.old_levels]
                q = stage.average([flux(t) for t in [t1, *times]])
                traction = wk.traction((t0, t1), h, stage, old)
                new = wk.advance(traction, q, h, stage, old)
                # the end's mean pressure is the capacitor's test level when R_p = 0
                assert traction.mean(q) == pytest.approx(new.mean, rel=1e-12)
                chain.insert(0, new)
                times.insert(0, t1)
            history = [new, *history]
        errors.append(abs(history[0].pressure - exact(1.0)))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - order) < 0.1), (errors, orders)


TINY = ("geometry.length=2.0", "mesh.nz=8", "mesh.nr=2", "time.end=0.002",
        'output.probes=[{ name = "eta_z1", quantity = "eta", z = 1.0 }]')
#: a Windkessel at the outlet of pulse-koiter: R_p the characteristic impedance ρ_f c/R (c = √(R C0/ρ_f)),
#: R_d ten times it, R_d C a few pulse durations
WINDKESSEL = rcr(888.0, 1e-5, 8880.0, 100.0)
COUPLERS = [
    '"kinematic-splitting"',
    '{model="kinematic-splitting",scheme="crank-nicolson",beta=1.0}',
    '{model="kinematic-splitting",beta=1.0}',
    '{model="kinematic-splitting",scheme="crank-nicolson"}',
    '{model="monolithic",scheme="backward-euler"}',
    '{model="monolithic",scheme="crank-nicolson"}',
    '{model="monolithic",scheme="bdf2"}',
    '{model="monolithic",scheme="tr-bdf2"}',
    '{model="kinematic-splitting",scheme="tr-bdf2"}',
    '{model="dirichlet-neumann-implicit",tolerance=1e-11}',
]


@pytest.mark.parametrize("coupler", COUPLERS)
def test_every_coupler_closes_the_ledger_with_an_rcr_outlet(tmp_path, coupler):
    result, data = run(tmp_path, "pulse-koiter", *TINY, WINDKESSEL, f"coupler={coupler}")
    assert result.status == "ok", result.reason
    s = data.series
    assert np.all(s["energy.relative_residual"] <= 1e-9)
    if "bdf2" not in coupler:  # the capacitor's energy ½ C P_c² (BDF2 carries its G-norm instead)
        assert np.allclose(s["stored.outlet"], 0.5 * 1e-5 * s["end.outlet.P_c"] ** 2, rtol=1e-12)
    assert np.max(s["end.outlet.P_c"]) > 100.0 and np.all(s["dissipation.outlet.distal"] >= 0.0)
    assert np.all(s["dissipation.outlet.proximal"] >= 0.0)
    if "tr-bdf2" not in coupler:  # (TR-BDF2's BDF2 stage hands over a G-norm's excess: either sign, theory §4)
        assert np.all(s["dissipation.outlet.numerical"] >= 0.0)


def test_a_light_wall_with_an_rcr_outlet_stays_stable(tmp_path):
    """ρ₁h/(ρ_f R) = 1e-3: the kinematic splitting keeps E ≤ E⁰ + work every step (the runner checks it) with
    the capacitor's energy in E and the distal pressure's work in the work."""
    result, data = run(tmp_path, "pulse-koiter", *TINY, "time.end=0.02", "layers[0].density=0.005", WINDKESSEL)
    assert result.status == "ok", result.reason
    s = data.series
    assert len(s["t"]) == 200 and np.all(s["energy.relative_residual"] <= 1e-9)
    work = np.cumsum(sum(s[k] for k in s if k.startswith("work.")))
    assert np.all(s["energy.total"] <= s["energy.total"][0] + work + 1e-9 * np.max(np.abs(s["energy.total"])))


def test_bad_windkessel_parameters_are_clear_errors():
    with pytest.raises(CaseError, match=r"loads.outlet.capacitance = -1.0: expected a number > 0.0"):
        load_case(CASES / "poiseuille-rigid.toml", [rcr(1.0, -1.0, 1.0)])
    with pytest.raises(CaseError, match=r"loads.outlet.distal: missing"):
        load_case(CASES / "poiseuille-rigid.toml", ['loads.outlet={model="windkessel",proximal=1.0,capacitance=1.0}'])
    # a Windkessel needs a fluid: the wall-only coupler refuses it
    with pytest.raises(CaseError, match=r"loads.outlet is set, but structure-only does not apply it"):
        load_case(CASES / "four-layer-wall.toml", [rcr(1.0, 1.0, 1.0)])




def test_a_run_with_an_rcr_outlet_resumes_bit_identical(tmp_path):
    """The capacitor's pressure is part of the fluid's state: a checkpoint carries it, and a run resumed from
    its checkpoint writes the same bytes as one that ran through (with the same checkpoints)."""
    assert_resume_is_bit_identical(tmp_path, "pulse-koiter", *TINY, WINDKESSEL)
