"""Thick band alone with sliding walls: mode frequencies ω = c √((mπ/L)² + (nπ/H)²)."""

import numpy as np
import pytest

from multilayer.coupling.structure import StructureStep
from multilayer.numerics.linsolve import SolverStats
from multilayer.numerics.signals import backward_euler_eigenvalue, prony_roots
from multilayer.numerics.timescheme import named
from multilayer.scene.state import State, WallState
from multilayer.wall.stack import Stack, WallSpace
from multilayer_plugins.linear_elastic import LinearElasticBand
from multilayer_plugins.planar import Planar

L, R, H = 2.0, 0.5, 0.5
BAND = LinearElasticBand.from_young_poisson(1.1, H, 1e6, 0.3, ends="sliding", faces="sliding")
CP, CS = BAND.wave_speeds


def mode(kind, m, n):
    """Exact sliding-wall modes on (0, L) × (R, R+H): P from a potential, S from a stream function."""
    kz, kr = m * np.pi / L, n * np.pi / H
    if kind == "P":  # d = ∇(cos kz z cos kr y)
        return (lambda z, r: -kz * np.sin(kz * z) * np.cos(kr * (r - R)),
                lambda z, r: -kr * np.cos(kz * z) * np.sin(kr * (r - R)), CP * np.hypot(kz, kr))
    return (lambda z, r: kr * np.sin(kz * z) * np.cos(kr * (r - R)),  # d = curl(sin sin)
            lambda z, r: -kz * np.cos(kz * z) * np.sin(kr * (r - R)), CS * np.hypot(kz, kr))


def measured_eigenvalue(kind, m, n, nz, nr, order, dt, steps=60):
    """Run free vibration from the interpolated mode; λ_h from the BE factor of its amplitude."""
    fz, fr, omega = mode(kind, m, n)
    space = WallSpace.build([BAND], Planar(), L, R, nz, order, [nr])
    stack = Stack.assemble(space)
    d0 = stack.zero_fixed(space.interpolate(lambda z, r, t: fz(z, r), lambda z, r, t: fr(z, r)))
    state = State(0, 0.0, WallState(d0, np.zeros_like(d0)))
    stats = SolverStats()
    step = StructureStep(stack, named("backward-euler"), dt, stats)
    Md0 = stack.mass @ d0
    amp = [1.0]
    for _ in range(steps):
        state = State(0, 0.0, step.step(state, {}).wall)
        amp.append(float(Md0 @ state.wall.d) / float(Md0 @ d0))
    z = prony_roots(np.array(amp), 2)
    z = z[np.argmax(np.angle(z))]
    return z, backward_euler_eigenvalue(z, dt), omega, stats


@pytest.mark.parametrize("kind,m,n", [("P", 1, 1), ("S", 1, 1), ("P", 2, 0)])
def test_sliding_band_mode_frequency_converges_at_order_2p(kind, m, n):
    # the P2 eigenvalue error is O(h^4), so ω_h − ω falls ~16x per halving
    dt = 1e-7
    errors = []
    for nz, nr in [(4, 2), (8, 4), (16, 8)]:
        _, lam, omega, _ = measured_eigenvalue(kind, m, n, nz, nr, 2, dt)
        errors.append(abs(abs(lam.imag) - omega) / omega)
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert errors[-1] < 1e-4
    assert np.all(orders > 3.5), (errors, orders)


def test_sliding_band_p1_converges_at_order_2():
    errors = []
    for nz, nr in [(8, 4), (16, 8), (32, 16)]:
        _, lam, omega, _ = measured_eigenvalue("P", 1, 1, nz, nr, 1, 1e-7)
        errors.append(abs(abs(lam.imag) - omega) / omega)
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 1.7), (errors, orders)


def test_backward_euler_time_error_is_first_order():
    # fixed mesh; the measured ω = arg(z)/Δt and decay ln|z|/Δt approach the
    # semi-discrete λ_h at first order in Δt (BE's numerical damping ≈ ω²Δt/2)
    nz, nr = 8, 4
    _, lam_h, _, _ = measured_eigenvalue("P", 1, 1, nz, nr, 2, 1e-8)
    errs = []
    for dt in (4e-5, 2e-5, 1e-5):
        z, _, _, _ = measured_eigenvalue("P", 1, 1, nz, nr, 2, dt, steps=80)
        errs.append(abs(np.log(abs(z)) / dt - lam_h.real))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(orders - 1.0) < 0.15), (errs, orders)


def test_matrix_is_factorized_once_per_run():
    *_, stats = measured_eigenvalue("P", 1, 1, 4, 2, 2, 1e-6, steps=25)
    assert stats.factorizations == 1
    assert stats.solves == 25


def test_the_kept_restrictions_are_the_prolongations_transposed():
    """WallSpace.restrictions[i] (kept: a step restricts to each line every step) is P_iᵀ, line by line."""
    space = WallSpace.build([BAND], Planar(), L, R, 6, 2, [2])
    x = np.arange(space.ndofs, dtype=float) ** 1.5
    assert len(space.restrictions) == len(space.prolongations) == 2
    for P, Rt in zip(space.prolongations, space.restrictions):
        assert np.array_equal(Rt @ x, P.T @ x)
