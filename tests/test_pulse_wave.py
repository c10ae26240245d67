"""Pulse-wave velocity as clinicians measure it (foot to foot, the ΔP–ΔA loop) and the stack's long-wave speed
(multilayer/campaign/pulse_wave.py): against prescribed travelling waves, Moens–Korteweg and Lamé."""

import math
from pathlib import Path

import numpy as np
import pytest

import multilayer as ml
from multilayer.campaign.pulse_wave import stack_long_wave_speed
from multilayer.plugin.registry import Registry
from multilayer.results.pulse import foot, foot_to_foot, loop_speed
from multilayer.wall.equilibrium import lumen_compliance
from multilayer.wall.stack import Stack, WallSpace
from multilayer_plugins.axisymmetric import Axisymmetric
from multilayer_plugins.linear_elastic import LinearElasticBand

CASES = Path(__file__).parents[1] / "cases"


def trapezoid(t, arrival, rise=2e-3, top=3e-3, height=1.0):
    """A pulse whose upstroke is a straight ramp starting at ``arrival``: the intersecting tangent is that ramp,
    its foot ``arrival`` exactly, wherever the rows fall."""
    s = t - arrival
    return height * np.clip(np.minimum(s / rise, (rise + top + rise - s) / rise), 0.0, 1.0)


@pytest.mark.parametrize("dt", [1e-4, 3.7e-5])
def test_foot_to_foot_of_a_prescribed_travelling_wave_is_its_speed(dt):
    c, t0 = 437.3, 1.3e-3
    t = dt * np.arange(1, round(0.03 / dt))
    zs = [1.0, 2.5, 4.0, 7.25]
    speed, feet = foot_to_foot([(f"p{i}", z, t, 1e4 + trapezoid(t, t0 + z / c, height=2e3)) for i, z in enumerate(zs)])
    assert speed.value == pytest.approx(c, rel=1e-11) and speed.reason == ""
    for i, z in enumerate(zs):
        assert feet[f"p{i}"].time == pytest.approx(t0 + z / c, rel=1e-11)
        assert feet[f"p{i}"].rise == pytest.approx(2e3, rel=1e-12)


def test_a_downgoing_pulse_has_its_foot_too():
    t = np.linspace(0.0, 0.02, 201)
    assert foot(t, -trapezoid(t, 0.0043)).time == pytest.approx(0.0043, rel=1e-12)


def test_the_foot_of_a_smooth_pulse_is_where_its_steepest_tangent_meets_the_baseline():
    """1 − cos: steepest at a quarter of its length, where it is at half height with slope πP/T; the rows' secant
    and midpoint stand for the tangent to second order in the row spacing."""
    T, start = 0.008, 0.002
    expected = start + T / 4 - 0.5 / (np.pi / T)
    errors = []
    for rows in (201, 401, 801):
        t = np.linspace(0.0, 0.02, rows) + 1e-6  # the steepest point between two rows
        y = 0.5 * (1 - np.cos(2 * np.pi * (t - start) / T)) * ((t > start) & (t < start + T))
        errors.append(abs(foot(t, y).time - expected))
    assert errors[0] < 2e-4 * T and all(e1 < e0 / 3.5 for e0, e1 in zip(errors, errors[1:])), errors


@pytest.mark.parametrize("series, reason", [
    (lambda t: np.zeros_like(t), "no upstroke"),
    (lambda t: trapezoid(t, 0.0195), "still steepening on the last row"),
    (lambda t: trapezoid(t, -0.0015), "the upstroke starts before the first row"),
])
def test_no_foot_says_why(series, reason):
    t = np.linspace(0.0, 0.02, 201)
    f = foot(t, series(t))
    assert f.time is None and reason in f.reason


def test_no_speed_without_two_feet_probes_too_close_or_no_arrival():
    t = np.linspace(0.0, 0.02, 201)  # rows 1e-4 s apart
    c = 500.0
    speed, _ = foot_to_foot([("a", 1.0, t, trapezoid(t, 1.0 / c)), ("b", 9.95, t, trapezoid(t, 9.95 / c))])
    assert speed.value is None and "fewer than two probes with a foot (b: " in speed.reason
    speed, _ = foot_to_foot([("a", 1.0, t, trapezoid(t, 1.0 / c)), ("b", 1.05, t, trapezoid(t, 1.05 / c))])
    assert speed.value is None and speed.reason.startswith("probes too close: the foot takes 0.0001 s")
    speed, feet = foot_to_foot([("a", 1.0, t, trapezoid(t, 1.0 / c)), ("b", 3.0, t, trapezoid(t, 3 / c, height=1e-3))])
    assert speed.value is None and "b: the pulse has not arrived: its rise is 0.1% of the largest" in speed.reason
    speed, _ = foot_to_foot([("a", 1.0, t, trapezoid(t, 3.0 / c)), ("b", 3.0, t, trapezoid(t, 1.0 / c))])
    assert speed.value is None and "the feet do not come later downstream" in speed.reason


@pytest.mark.parametrize("k", [0, 1])
def test_the_pressure_area_loop_of_a_linear_wall_gives_its_long_wave_speed(k):
    """η = P/C0 (a wall without inertia): c² = A/ρ · dP/dA = a C0/ρ, a = R/(1 + k), up to (1 + η/R) ~ 1e-9."""
    R, C0, rho = 0.5, 4.0e5, 1.06
    t = np.linspace(0.0, 0.02, 401)
    p = 1e-3 * (1 - np.cos(2 * np.pi * (t - 0.003) / 0.01)) * ((t > 0.003) & (t < 0.013))
    speed = loop_speed(t, 1e5 + p, p / C0, R, k, rho)
    assert speed.value == pytest.approx(math.sqrt(R / (1 + k) * C0 / rho), rel=1e-7)
    assert "fewer than 3 rows" in loop_speed(t[::40], p[::40], p[::40] / C0, R, k, rho).reason
    assert loop_speed(t, p, 0 * p, R, k, rho).reason == "the lumen does not move in early systole"


def shell(h=0.01, E=1.6e7, s=0.3):
    return {"model": "koiter-shell", "density": 1.1, "thickness": h, "young": E, "poisson": s}


def band(H, E, s, cells=4):
    return {"model": "linear-elastic", "density": 1.1, "thickness": H, "young": E, "poisson": s, "cells": cells}


def resolved(kind, layers, R=0.5, L=6.0, nz=24):
    case = ml.load_case(CASES / "pulse-koiter-thick.toml",
                        {"geometry.model": kind, "geometry.radius": R, "geometry.length": L, "mesh.nz": nz,
                         "mesh.nr": 2, "layers": layers, "coupler": "monolithic"})
    return dict(case.resolved)


def test_the_stack_speed_of_a_thin_shell_is_moens_korteweg():
    """A Koiter shell alone: c² = R C0/(2ρ_f) in a tube (Moens–Korteweg: Eh/(2ρ_f R (1 − σ²)) to O(h²/R²)),
    R C0/ρ_f in the planar channel."""
    h, E, s, R, rho = 0.01, 1.6e7, 0.3, 0.5, 1.0  # pulse-koiter-thick's fluid: ρ_f = 1
    C0 = E * h / (R**2 * (1 - s**2)) * (1 + h**2 / (12 * R**2))
    for kind, a in (("axisymmetric", R / 2), ("planar", R)):
        speed = stack_long_wave_speed(resolved(kind, [shell(h, E, s)]), Registry.load())
        assert speed.value == pytest.approx(math.sqrt(a * C0 / rho), rel=1e-8), kind


def lame(R, H, E, s):
    """u_r/p at r = R of a thick tube R < r < R + H under an inner pressure p, outer face free, plane strain."""
    b = R + H
    return R * (1 + s) / E * ((1 - 2 * s) * R**2 + b**2) / (b**2 - R**2)


def test_a_bands_compliance_is_lames_thick_walled_tube():
    """A band alone in a tube, its ends sliding (d_z = 0 there): the plane-strain Lamé solution, u_r = A r + B/r,
    meets every condition, so only the radial discretization (P2 against 1/r) is left: it converges."""
    R, H, E, s = 0.5, 0.1, 2.0e6, 0.45
    band = LinearElasticBand.from_young_poisson(1.1, H, E, s, ends="sliding")
    errors = []
    for cells in (1, 2, 4):
        stack = Stack.assemble(WallSpace.build([band], Axisymmetric(), 6.0, R, 24, 2, [cells]))
        compliance = lumen_compliance(stack)
        errors.append(np.max(np.abs(compliance / lame(R, H, E, s) - 1)))
    assert errors[-1] < 5e-5 and all(e1 < e0 / 4 for e0, e1 in zip(errors, errors[1:])), errors


def test_the_stack_speed_counts_every_layer_thin_and_thick():
    """A Koiter shell on a band: the shell holds the band's inner face axially (plane strain), and the two
    stiffnesses dP/dη add: C0 + 1/(Lamé's u_r/p).  Refining the band's radial cells converges to it."""
    R, H, E, s, rho = 0.5, 0.1, 2.0e6, 0.45, 1.0
    h, Es = 0.01, 1.6e7
    C0 = Es * h / (R**2 * (1 - 0.3**2)) * (1 + h**2 / (12 * R**2))
    exact = math.sqrt(R / 2 * (C0 + 1 / lame(R, H, E, s)) / rho)
    errors = []
    for cells in (1, 2, 4):
        speed = stack_long_wave_speed(resolved("axisymmetric", [shell(h, Es), band(H, E, s, cells)]), Registry.load())
        errors.append(abs(speed.value / exact - 1))
    assert errors[-1] < 2e-5 and all(e1 < e0 / 4 for e0, e1 in zip(errors, errors[1:])), errors


def test_a_wall_whose_ends_carry_the_load_has_no_long_wave_speed():
    membrane = {"model": "wave-membrane", "density": 1.1, "thickness": 0.02, "tension": 2e5}
    speed = stack_long_wave_speed(resolved("axisymmetric", [membrane]), Registry.load())
    assert speed.value is None and "varies by 25% along z: its ends carry part of the load" in speed.reason
    case = resolved("axisymmetric", [shell()])
    assert stack_long_wave_speed({**case, "fluid": None}, Registry.load()).reason == "no fluid"
