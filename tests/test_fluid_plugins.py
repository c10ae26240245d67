"""The ``navier-stokes`` and ``stokes`` plugins and the fluid API's errors."""

import numpy as np
import pytest
from fluid_steps import BE, fluid_step, setup_fluid
from skfem import BilinearForm, asm

from multilayer.fluid.contract import Domain, Fluid, Interface
from multilayer.plugin.registry import Registry
from multilayer_plugins.channel import ChannelFluid, NavierStokes, Stokes


@pytest.mark.parametrize("name, cls, ends", [("navier-stokes", NavierStokes, ["ends", "backflow"]),
                                             ("stokes", Stokes, [])])
def test_registered_with_density_and_viscosity(name, cls, ends):
    record = Registry.load().get("fluid", name).record
    stabilization = ["stabilization", "grad_div", "supg_dt"] if cls is NavierStokes else []
    assert [p.name for p in record.params] == ["density", "viscosity", *ends, *stabilization]
    assert all(p.gt == 0.0 and p.required for p in record.params[:2])
    assert not any(p.required for p in record.params[2:])
    assert [p.default for p in record.params[4:]] == (["supg", 0.1, None] if stabilization else [])
    fluid = record.factory(density=1.06, viscosity=0.035)
    assert isinstance(fluid, cls) and isinstance(fluid, ChannelFluid) and isinstance(fluid, Fluid)
    assert (fluid.density, fluid.viscosity) == (1.06, 0.035)


def test_the_two_fluids_differ_only_in_advection():
    assert NavierStokes.advection and not Stokes.advection
    assert NavierStokes.__mro__[1] is Stokes.__mro__[1] is ChannelFluid


@pytest.mark.parametrize("kwargs", [{"density": 0.0, "viscosity": 1.0}, {"density": 1.0, "viscosity": -1.0}])
def test_rejects_non_positive_parameters(kwargs):
    with pytest.raises(ValueError, match="must be > 0"):
        Stokes(**kwargs)


def setup(wall, order=2):
    fluid = NavierStokes(1.0, 0.035)
    setup_fluid(fluid, 1.0, 0.5, nz=2, nr=2, order=order, wall=wall)
    return fluid


def test_line_is_the_canonical_interface_line():
    fluid = setup("coupled")
    assert fluid.line.order == 2 and fluid.line.radius == 0.5 and fluid.line.ndofs == 5
    ch = fluid.channel
    wall_dof = ch.prolongation.tocsc().indices  # velocity DOF of each line DOF
    assert np.allclose(ch.velocity.doflocs[:, wall_dof], [fluid.line.z, np.full(5, 0.5)])
    assert set(wall_dof) == set(ch.wall_r) and np.all(wall_dof % 2 == 1)  # u_r DOFs
    u = np.arange(ch.velocity.N, dtype=float)
    assert np.array_equal(ch.wall_trace(u), u[wall_dof])  # the kept restriction is Pᵀ


def test_wall_mode_errors():
    with pytest.raises(ValueError, match="wall mode"):
        setup("elastic")
    rigid = setup("rigid")
    state = rigid.initial_state()
    with pytest.raises(ValueError, match="rigid wall does not move"):
        fluid_step(rigid, state, 1e-3, eta=np.full(rigid.line.ndofs, 0.01))
    prescribed = setup("prescribed")
    with pytest.raises(ValueError, match="vanish at z = 0"):
        fluid_step(prescribed, state, 1e-3, np.zeros(5), np.ones(5))
    with pytest.raises(ValueError, match="only enter the coupled"):
        fluid_step(prescribed, state, 1e-3, robin_mass=np.eye(5))
    with pytest.raises(ValueError, match="interface line"):
        fluid_step(setup("coupled"), state, 1e-3, eta=np.zeros(3))
    with pytest.raises(ValueError, match="5 × 5"):
        setup("coupled").step([state], Domain.still(5), BE, 1e-3, (0.0, 1e-3), interface=Interface(np.eye(3), np.zeros(3)))
    with pytest.raises(ValueError, match="closes the channel"):
        fluid_step(setup("coupled"), state, 1e-3, eta=-np.ones(5))
    with pytest.raises(ValueError, match="time step"):
        fluid_step(setup("coupled"), state, 0.0)
    with pytest.raises(RuntimeError, match="setup"):
        Stokes(1.0, 1.0).initial_state()
    with pytest.raises(ValueError, match="order"):
        setup_fluid(Stokes(1.0, 1.0), 1.0, 0.5, 2, 2, order=3)


def test_probes_on_a_deformed_channel():
    fluid = setup("coupled")
    eta = 0.1 * np.sin(np.pi * fluid.line.z)
    state = fluid.initial_state(lambda z, r: (1.0 + 0 * r, 0 * r), eta)  # plug flow in the physical domain
    assert fluid.flow_rate(state, eta, 0.5) == pytest.approx(0.6, rel=1e-12)  # (R + η(½)) · 1
    assert np.allclose(fluid.velocity(state, eta, [0.5, 0.5], [0.0, 0.59]), [[1.0, 1.0], [0.0, 0.0]])
    area = 0.5 + float(np.sum(asm(BilinearForm(lambda u, v, w: u * v), fluid.line.basis) @ eta))
    assert fluid.kinetic_energy(state, eta) == pytest.approx(0.5 * area, rel=1e-12)
