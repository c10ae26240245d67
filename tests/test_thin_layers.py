"""Thin layers (``wave-membrane``, ``koiter-shell``) against their dispersion relation.

theory §8: a thin layer alone with pinned, simply supported ends has the
modes sin(kz), k = nπ/L, with

    ρ₁h λ² + (D0 + D1k² + D2k⁴) λ + (C0 + C1k² + C2k⁴) = 0.

The orders asserted below are the ones of the math (each test says why);
the measured ones, from a refinement study, are quoted in docs/thin-layers.md.
"""

from __future__ import annotations

import attrs
import numpy as np
import pytest
import scipy.linalg as sla

from multilayer.coupling.structure import StructureStep
from multilayer.geometry.spaces import make_line_space
from multilayer.numerics.linsolve import SolverStats
from multilayer.numerics.timescheme import named
from multilayer.plugin.registry import Registry
from multilayer.scene.state import State, WallState
from multilayer.wall.layer import LayerMatrices
from multilayer.wall.stack import Stack, WallSpace
from multilayer_plugins.koiter_shell import KoiterShell, koiter_shell
from multilayer_plugins.planar import Planar
from multilayer_plugins.thin_shell import KoiterFamilyLayer
from multilayer_plugins.wave_membrane import wave_membrane

L, R, RHO, H = 6.0, 0.5, 1.1, 0.1

MEMBRANE = wave_membrane(RHO, H, tension=2.0e3)
# Coefficients chosen so that every term of the symbol matters for n = 1..3
# (mode 1: C0 : C1k² : C2k⁴ ≈ 1000 : 274 : 752).
SHELL = KoiterFamilyLayer(RHO, H, C0=1.0e3, C1=1.0e3, C2=1.0e4)
BENDING = KoiterFamilyLayer(RHO, H, C2=1.0e4)
# Underdamped for n = 1..3 (mode 3: decay 330 s⁻¹ < frequency 765 s⁻¹).
DAMPED = attrs.evolve(SHELL, D0=2.0, D1=4.0, D2=10.0)
MODES = np.arange(1, 4)


# -- the exact relation --------------------------------------------------------


def symbol(c0: float, c1: float, c2: float, k: np.ndarray) -> np.ndarray:
    return c0 + c1 * k**2 + c2 * k**4


def exact_lambda(layer: KoiterFamilyLayer, n: np.ndarray) -> np.ndarray:
    """The root with Im λ ≥ 0 of ρ₁h λ² + d(k) λ + c(k) = 0."""
    k = n * np.pi / L
    m = layer.density * layer.thickness
    c = symbol(layer.C0, layer.C1, layer.C2, k)
    d = symbol(layer.D0, layer.D1, layer.D2, k)
    return (-d + np.sqrt(d**2 - 4 * m * c + 0j)) / (2 * m)


# -- the discrete problem ------------------------------------------------------


def pinned(layer, nz: int, order: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Dense M, C, K of ``layer`` restricted to the free DOFs."""
    space = make_line_space(L, nz, order, R, Planar())
    m = layer.forms(space)
    free = np.setdiff1d(np.arange(space.ndofs), layer.essential_dofs(space))
    pick = np.ix_(free, free)
    return m.mass.toarray()[pick], m.damping.toarray()[pick], m.stiffness.toarray()[pick]


def discrete_omegas(layer, nz: int, order: int) -> np.ndarray:
    M, _, K = pinned(layer, nz, order)
    return np.sqrt(sla.eigh(K, M, eigvals_only=True)[: MODES.size])


def discrete_lambdas(layer, nz: int, order: int) -> np.ndarray:
    """Eigenvalues of (λ²M + λC + K)x = 0 through the companion pencil, Im λ > 0, by |λ|."""
    M, C, K = pinned(layer, nz, order)
    n = M.shape[0]
    eye, zero = np.eye(n), np.zeros((n, n))
    lam = sla.eig(np.block([[zero, eye], [-K, -C]]), np.block([[eye, zero], [zero, M]]), right=False)
    lam = lam[lam.imag > 0]
    # |λ|² = c(k)/(ρ₁h) grows with k, so |λ| orders the underdamped modes.
    return lam[np.argsort(np.abs(lam))][: MODES.size]


def orders(errors: list[np.ndarray]) -> np.ndarray:
    """Observed orders under halving of h (or Δt), one row per halving."""
    e = np.array(errors)
    return np.log2(e[:-1] / e[1:])


# Meshes in the asymptotic range and above the round-off floor of the dense
# eigensolver (relative ≈ 1e-9 here: the pencil's condition grows like nz⁴).
MESHES = {1: (16, 32, 64), 2: (6, 12, 24)}


def undamped_errors(layer, order: int) -> np.ndarray:
    """|ω_h/ω − 1| on MESHES[order] (rows) for modes 1..3 (columns)."""
    exact = np.abs(exact_lambda(layer, MODES))
    return np.array([np.abs(discrete_omegas(layer, nz, order) / exact - 1) for nz in MESHES[order]])


def damped_errors(order: int) -> np.ndarray:
    """|λ_h/λ − 1| on MESHES[order] (rows) for modes 1..3 (columns)."""
    exact = exact_lambda(DAMPED, MODES)
    return np.array([np.abs(discrete_lambdas(DAMPED, nz, order) / exact - 1) for nz in MESHES[order]])


@pytest.mark.parametrize(
    ("layer", "order", "expected"),
    [
        # P1: Galerkin eigenvalues err by O(h^{2p}) = O(h²).
        (MEMBRANE, 1, 2.0),
        (SHELL, 1, 2.0),
        # Bending alone, P1 on a uniform mesh: sin(kz) is an exact discrete
        # eigenvector and ω_h² = C2 (4 sin²(kh/2)/h²)² · 3/(2 + cos kh)/(ρ₁h)
        # = ω² (1 + O((kh)⁴)): the lumped κ_h and the consistent mass cancel at h².
        (BENDING, 1, 4.0),
        # P2: O(h^{2p}) = O(h⁴); the lumped mass in κ_h is Simpson's rule, whose
        # error on the P2 products is O(h⁴), so it keeps the order.
        (MEMBRANE, 2, 4.0),
        (SHELL, 2, 4.0),
        (BENDING, 2, 4.0),
    ],
    ids=["membrane-P1", "shell-P1", "bending-P1", "membrane-P2", "shell-P2", "bending-P2"],
)
def test_dispersion_undamped(layer, order, expected):
    """ω_n → √(c(k)/(ρ₁h)) at the order of the element, modes 1..3."""
    errors = undamped_errors(layer, order)
    measured = orders(errors)
    assert measured.min() >= expected - 0.3, f"orders {measured} (errors {errors})"


@pytest.mark.parametrize(("order", "expected"), [(1, 2.0), (2, 4.0)])
def test_dispersion_damped(order, expected):
    """λ_n of the quadratic eigenproblem → the root of the damped relation, modes 1..3."""
    errors = damped_errors(order)
    measured = orders(errors)
    assert measured.min() >= expected - 0.3, f"orders {measured} (errors {errors})"


# -- time domain: the core A1 step on a lone shell -------------------------------


def prony(a: np.ndarray) -> complex:
    """z with Im z ≥ 0 of the recurrence a^{n+1} = p aⁿ + q a^{n−1}, fitted by least squares."""
    (p, q), *_ = np.linalg.lstsq(np.column_stack([a[1:-1], a[:-2]]), a[2:], rcond=None)
    roots = np.roots([1.0, -p, -q])
    return complex(roots[np.argmax(roots.imag)])


def amplification(layer, nz: int, dt: float, steps: int) -> tuple[complex, complex]:
    """(z measured from η at the antinode, semi-discrete λ_h of mode 1) with P1."""
    wall = WallSpace.build([layer], Planar(), L, R, nz, 1)
    stack = Stack.assemble(wall)
    z = wall.lines[0].z
    mode = np.sin(np.pi * z / L)
    mode[stack.fixed] = 0.0
    # On a uniform P1 mesh sin(kz) is an exact eigenvector of M, C and K, so
    # the signal holds one conjugate pair and λ_h solves a scalar quadratic.
    m, c, k = (float(mode @ A @ mode) for A in (stack.mass, stack.damping, stack.stiffness))
    Kx, Mx = stack.stiffness[stack.free] @ mode, stack.mass[stack.free] @ mode
    scale = (abs(stack.stiffness[stack.free]) @ np.abs(mode)).max()
    assert np.abs(Kx - k / m * Mx).max() < 1e-13 * scale
    lam_h = (-c + np.sqrt(complex(c * c - 4 * m * k))) / (2 * m)

    step = StructureStep(stack, named("backward-euler"), dt, SolverStats())
    state = State(0, 0.0, WallState(d=mode.copy(), V=np.zeros_like(mode)))
    antinode = int(np.argmin(np.abs(z - L / 2)))
    signal = [state.wall.d[antinode]]
    for _ in range(steps):
        state = State(0, 0.0, step.step(state, {}).wall)
        signal.append(state.wall.d[antinode])
    return prony(np.array(signal)), lam_h


# nz = 64: the space error (1.4e-5 relative) is below 1 % of the smallest time
# error, and round-off, amplified by the condition of M/Δt² + C/Δt + K (≈ 1e5,
# growing like nz⁴), leaves λ_hΔt = 1 − 1/z exact to ≈ 1e-11.
TIME_NZ, TIME_END, TIME_STEPS = 64, 0.1, (1e-3, 5e-4, 2.5e-4, 1.25e-4)


def time_errors() -> tuple[np.ndarray, np.ndarray]:
    """Per Δt of TIME_STEPS: |(1 − 1/z) − λ_hΔt|, and (|ω_meas − ω|, |decay − Re λ|) against exact λ.

    ω_meas = |arg z|/Δt and decay = ln|z|/Δt.
    """
    exact = complex(exact_lambda(DAMPED, np.array([1]))[0])
    round_off, errors = [], []
    for dt in TIME_STEPS:
        zeta, lam_h = amplification(DAMPED, TIME_NZ, dt, int(round(TIME_END / dt)))
        round_off.append(abs((1 - 1 / zeta) - lam_h * dt))
        omega, decay = abs(np.angle(zeta)) / dt, np.log(abs(zeta)) / dt
        errors.append([abs(omega - exact.imag), abs(decay - exact.real)])
    return np.array(round_off), np.array(errors)


def test_time_domain_backward_euler():
    """z = 1/(1 − λ_h Δt) to round-off, and ω, decay → exact at first order in Δt.

    For λ = −α + iω, ln z /Δt = −ln(1 − λΔt)/Δt = λ + λ²Δt/2 + O(Δt²): the decay
    errs by (α² − ω²)Δt/2 and the frequency by −αωΔt, both first order (the
    frequency error would be second order without damping).
    """
    round_off, errors = time_errors()
    assert round_off.max() < 1e-10
    measured = orders(errors)
    assert measured.min() >= 1.0 - 0.3, f"orders {measured} (errors {errors})"
    assert measured.max() <= 1.0 + 0.3, f"orders {measured}: BE should not look better than first order"
    # The leading terms themselves; the next ones are smaller by ≈ ω²Δt/(3α) < 5 %.
    exact = complex(exact_lambda(DAMPED, np.array([1]))[0])
    alpha, omega = -exact.real, exact.imag
    leading = np.array([alpha * omega, (omega**2 - alpha**2) / 2]) * TIME_STEPS[-1]
    np.testing.assert_allclose(errors[-1], leading, rtol=0.1)


# -- coefficients and parameters -------------------------------------------------


def scheme_coefficients(h, E, s, Rad):
    """theory §1, typed again from the text."""
    return (
        h * E / (Rad**2 * (1 - s**2)) * (1 + h**2 / (12 * Rad**2)),
        h**3 * E * s / (6 * Rad**2 * (1 - s**2)),
        h**3 * E / (12 * (1 - s**2)),
    )


def test_koiter_coefficients_from_young_poisson():
    layer = KoiterFamilyLayer.from_young_poisson(RHO, H, young=1e6, poisson=0.3, radius=R,
                                                 viscous_young=3e3, viscous_poisson=0.2)
    got = (layer.C0, layer.C1, layer.C2, layer.D0, layer.D1, layer.D2)
    want = scheme_coefficients(H, 1e6, 0.3, R) + scheme_coefficients(H, 3e3, 0.2, R)
    np.testing.assert_allclose(got, want, rtol=1e-14)
    assert layer.long_wave_stiffness() == layer.C0


def test_koiter_shell_takes_the_radius_of_its_line():
    shell = koiter_shell(density=RHO, thickness=H, young=1e6, poisson=0.3)
    assert isinstance(shell, KoiterShell)
    assert shell.viscous_poisson == 0.3 and shell.viscous_young == 0.0
    for radius in (0.5, 0.7):
        space = make_line_space(L, 8, 2, radius, Planar())
        want = KoiterFamilyLayer.from_young_poisson(RHO, H, 1e6, 0.3, radius).forms(space)
        got = shell.forms(space)
        assert abs(got.stiffness - want.stiffness).max() == 0.0
        assert shell.long_wave_stiffness(radius) == scheme_coefficients(H, 1e6, 0.3, radius)[0]
    with pytest.raises(ValueError, match="radius"):
        shell.long_wave_stiffness()
    own = koiter_shell(density=RHO, thickness=H, young=1e6, poisson=0.3, radius=0.4)
    space = make_line_space(L, 8, 1, R, Planar())
    want = KoiterFamilyLayer.from_young_poisson(RHO, H, 1e6, 0.3, 0.4)
    assert abs(own.forms(space).stiffness - want.forms(space).stiffness).max() == 0.0
    assert own.long_wave_stiffness() == want.C0


def test_koiter_shell_given_by_coefficients():
    layer = koiter_shell(density=RHO, thickness=H, C0=1.0, C1=2.0, C2=3.0, D1=4.0, young=None)
    assert layer == KoiterFamilyLayer(RHO, H, 1.0, 2.0, 3.0, 0.0, 4.0, 0.0)


@pytest.mark.parametrize(
    ("params", "match"),
    [
        (dict(young=1e6, poisson=0.3, C0=1.0, C1=0.0, C2=1.0), "young, poisson and C0, C1, C2"),
        (dict(C0=1.0, C1=0.0, C2=1.0, viscous_young=1.0), "viscous_young and C0"),
        (dict(young=1e6, poisson=0.3, D0=1.0), "not both"),
        (dict(young=1e6), "missing poisson"),
        (dict(poisson=0.3), "missing young"),
        (dict(), "missing young, poisson"),
        (dict(C0=1.0, C2=1.0), "missing C1"),
        (dict(young=1e6, poisson=0.5), "poisson"),
        (dict(young=1e6, poisson=-1.0), "poisson"),
        (dict(young=1e6, poisson=0.3, viscous_poisson=0.5), "viscous_poisson"),
        (dict(young=0.0, poisson=0.3), "young"),
        (dict(young=1e6, poisson=0.3, radius=0.0), "radius"),
        (dict(C0=1.0, C1=-2.1, C2=1.0), "C1"),
        (dict(C0=1.0, C1=0.0, C2=-1.0), "C2"),
    ],
)
def test_koiter_shell_rejects(params, match):
    with pytest.raises(ValueError, match=match):
        koiter_shell(density=RHO, thickness=H, **params)


def test_membrane_rejects_negative_tension():
    with pytest.raises(ValueError, match="C1"):
        wave_membrane(RHO, H, tension=-1.0)


def test_plugins_are_registered():
    reg = Registry.load()
    for name, factory in (("wave-membrane", wave_membrane), ("koiter-shell", koiter_shell)):
        record = reg.get("layer", name).record
        assert record.thin and record.factory is factory and record.doc
        assert all(p.unit or p.name in ("poisson", "viscous_poisson") for p in record.params)
    poisson = reg.get("layer", "koiter-shell").record.param("poisson")
    assert (poisson.gt, poisson.lt) == (-1.0, 0.5)


# -- the matrices ----------------------------------------------------------------

AUXETIC = KoiterFamilyLayer.from_young_poisson(RHO, H, 1e6, -0.9, R, viscous_young=1e3)


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("layer", [MEMBRANE, SHELL, DAMPED, AUXETIC], ids=["membrane", "shell", "damped", "auxetic"])
def test_matrices_symmetric_semidefinite(layer, order):
    space = make_line_space(L, 12, order, R, Planar())
    m = layer.forms(space)
    assert isinstance(m, LayerMatrices)
    np.testing.assert_array_equal(layer.essential_dofs(space), space.end_dofs)
    for name in ("mass", "damping", "stiffness"):
        A = getattr(m, name)
        assert A.format == "csr" and A.shape == (space.ndofs, space.ndofs)
        assert abs(A - A.T).max() == 0.0, name
        eig = np.linalg.eigvalsh(A.toarray())
        assert eig.min() >= -1e-12 * max(eig.max(), 1.0), (name, eig.min())
    assert np.linalg.eigvalsh(m.mass.toarray()).min() > 0


ENERGY_MESHES = (12, 24, 48)


def energy_errors(order: int) -> np.ndarray:
    """|½ηᵀKη / E − 1| for the interpolant of sin(πz/L) + 0.3 sin(3πz/L), on ENERGY_MESHES."""
    a, b = np.pi / L, 3 * np.pi / L

    def eta(z):
        return np.sin(a * z) + 0.3 * np.sin(b * z)

    c0, c1, c2 = SHELL.C0, SHELL.C1, SHELL.C2
    exact = 0.5 * (L / 2) * (c0 * 1.09 + c1 * (a**2 + 0.09 * b**2) + c2 * (a**4 + 0.09 * b**4))
    errors = []
    for nz in ENERGY_MESHES:
        space = make_line_space(L, nz, order, R, Planar())
        errors.append(abs(SHELL.forms(space).elastic(eta(space.z)) / exact - 1))
    return np.array(errors)


# P1: the interpolant's energy errs by O(h²).  P2: by O(h⁴) on a uniform mesh,
# since the leading interpolation error (z−z₀)(z−z₁)(z−z₂)η‴/6 is odd on each
# cell, so its moments against smooth functions cancel at h³.
@pytest.mark.parametrize(("order", "expected"), [(1, 2.0), (2, 4.0)])
def test_elastic_energy_of_a_smooth_shape(order, expected):
    """½ηᵀKη of the interpolant → ½∫ C0η² + C1η_z² + C2η_zz² at the order of the element."""
    errors = energy_errors(order)
    measured = orders(errors)
    assert measured.min() >= expected - 0.3, f"orders {measured} (errors {errors})"


if __name__ == "__main__":  # the refinement study quoted in docs/thin-layers.md
    np.set_printoptions(formatter={"float": "{:.4g}".format})
    for name, layer in (("membrane", MEMBRANE), ("shell", SHELL), ("bending", BENDING)):
        for order in (1, 2):
            e = undamped_errors(layer, order)
            print(f"undamped {name} P{order} nz={MESHES[order]} finest error {e[-1]} orders\n{orders(e)}")
    for order in (1, 2):
        e = damped_errors(order)
        print(f"damped P{order} nz={MESHES[order]} finest error {e[-1]} orders\n{orders(e)}")
    round_off, e = time_errors()
    print(f"time dt={TIME_STEPS} |(1 − 1/z) − λ_hΔt| {round_off}\n(ω, decay) errors\n{e}\norders\n{orders(e)}")
    for order in (1, 2):
        e = energy_errors(order)
        print(f"energy P{order} nz={ENERGY_MESHES} errors {e} orders {orders(e)}")
