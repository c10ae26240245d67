"""The A1 energy identity of theory §7 closes to round-off on a thin+thick+thin+thick stack."""

import attrs
import numpy as np
import pytest

from multilayer.coupling.structure import StructureStep
from multilayer.numerics.linsolve import SolverStats
from multilayer.numerics.timescheme import named, schemes
from multilayer.runner import ledger
from multilayer.scene.state import State, WallState
from multilayer.wall.stack import Stack, WallSpace
from multilayer_plugins.koiter_shell import koiter_shell
from multilayer_plugins.linear_elastic import LinearElasticBand
from multilayer_plugins.planar import Planar
from multilayer_plugins.wave_membrane import wave_membrane

L, R = 6.0, 0.5


def four_layer_stack(order, nz=24):
    layers = [
        koiter_shell(density=1.1, thickness=0.02, young=1e6, poisson=0.45, viscous_young=50.0),
        LinearElasticBand.from_young_poisson(1.1, 0.1, 8e5, 0.45),
        wave_membrane(density=1.2, thickness=0.01, tension=2e3),
        LinearElasticBand.from_young_poisson(1.0, 0.05, 3e5, 0.3),
    ]
    space = WallSpace.build(layers, Planar(), L, R, nz, order, [None, 3, None, 2])
    return space, Stack.assemble(space)


def test_stack_places_thin_layers_on_band_boundaries():
    space, stack = four_layer_stack(2)
    assert [p.line for p in space.placements] == [0, None, 1, None]
    assert [p.band for p in space.placements] == [None, 0, None, 1]
    assert [ln.radius for ln in space.lines] == pytest.approx([0.5, 0.6, 0.65])
    # thin-layer DOFs are the radial DOFs of the band on that line
    r_dofs = set(space.basis.split_indices()[1])
    assert set(space.line_dofs(1)) <= r_dofs
    assert np.allclose(space.basis.doflocs[1, space.line_dofs(1)], 0.6)
    # d_z = 0 under the thin layers; clamped band ends
    assert set(space.tangential_dofs_on(0)) <= set(stack.fixed)
    assert set(space.tangential_dofs_on(1)) <= set(stack.fixed)
    for M in (stack.mass, stack.damping, stack.stiffness):
        assert abs(M - M.T).max() < 1e-9 * abs(M).max()


@pytest.mark.parametrize("scheme", sorted(schemes()))
@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("fluid_updates_v", [False, True])
def test_wall_energy_identity_closes_every_step(order, fluid_updates_v, scheme):
    """Every time scheme's identity (stored energy, numerical dissipation) on the four-layer stack."""
    space, stack = four_layer_stack(order)
    dt, steps = 2e-5, 220
    S = named(scheme)
    d0 = space.interpolate(lambda z, r, t: 0.0 * z,
                           lambda z, r, t: 0.01 * np.sin(np.pi * z / L) * np.exp(-(r - R) / 0.1))
    state = State(0, 0.0, WallState(stack.zero_fixed(d0), np.zeros(space.ndofs)),
                  v=np.zeros(space.lines[0].ndofs) if fluid_updates_v else None)
    step = StructureStep(stack, S, dt, SolverStats(), fluid_line=0 if fluid_updates_v else None)
    outer, lumen = space.line_load(space.outer_line), space.line_load(0)
    previous = sum(step.energy(state).values())
    rng = np.random.default_rng(1)
    worst = 0.0
    for n in range(steps):
        t = n * dt
        if fluid_updates_v:
            # what a fluid step does: hands back a thin-layer velocity of its own
            v = state.v + 0.1 * rng.standard_normal(state.v.shape) * np.abs(state.v).max(initial=1e-3)
            v[space.lines[0].end_dofs] = 0.0
            state = State(state.n, t, state.wall, v=v, previous=state.previous)
            previous = sum(step.energy(state).values())
        numerical, start = 0.0, state
        for stage, t0, t1, h in S.substeps(t, t + dt, dt):  # a multi-stage scheme's stages, each from the one before
            forces = {"external": -300.0 * np.sin(2e3 * t0) * outer,
                      "interface": 1e3 * (1 + np.cos(3e3 * t0)) * lumen}
            out = step.using(stage).step(state, forces, h)
            state = state.then(stage.levels - 1, n=n + 1, t=t1, wall=out.wall, v=out.v)
            row = ledger.close(out.stored, previous, out.work, out.dissipation)
            previous = row["energy.total"]
            worst = max(worst, row["energy.relative_residual"])
            numerical += row["dissipation.numerical.wall"]
        state = attrs.evolve(state, previous=start.trimmed(S.levels - 2))  # the step's levels, not its stages'
        if scheme != "crank-nicolson":
            assert numerical > 0
    if scheme == "crank-nicolson":  # conserves: no numerical dissipation at all
        assert row["dissipation.numerical.wall"] == 0.0
    assert row["dissipation.viscous.layers[0]"] > 0  # the viscous Koiter shell dissipates
    print(f"{scheme}: worst relative residual {worst:.2e}")
    assert worst <= 1e-10, worst


def test_identity_detects_a_wrong_term():
    # the ledger is not vacuous: dropping the numerical dissipation breaks it
    space, stack = four_layer_stack(1, nz=8)
    d0 = space.interpolate(lambda z, r, t: 0.0 * z, lambda z, r, t: 0.01 * np.sin(np.pi * z / L))
    state = State(0, 0.0, WallState(stack.zero_fixed(d0), np.zeros(space.ndofs)))
    step = StructureStep(stack, named("backward-euler"), 1e-4, SolverStats())
    previous = sum(step.energy(state).values())
    out = step.step(state, {})
    dissipation = dict(out.dissipation)
    dissipation.pop("dissipation.numerical.wall")
    assert ledger.close(out.stored, previous, out.work, dissipation)["energy.relative_residual"] > 1e-3
