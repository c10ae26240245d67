"""One fluid step as the couplers take it, for the fluid's own tests."""

import numpy as np

from multilayer.boundary.contract import BoundaryCondition, EndTraction
from multilayer.fluid.contract import Domain, FluidSetup, Interface
from multilayer.numerics.timescheme import named
from multilayer_plugins.planar import Planar

BE = named("backward-euler")


class Given(BoundaryCondition):
    """An end whose pressure the test sets before each step (p̄ as given, no resistance)."""

    def __init__(self):
        self.pressure = 0.0

    def traction(self, window, dt, scheme, history) -> EndTraction:
        return EndTraction(self.pressure)


def setup_fluid(fluid, length, radius, nz, nr, ends=None, geometry=None, **options):
    """``fluid.setup`` on the channel L × R (planar unless ``geometry`` is given), each end a :class:`Given`
    pressure (0 until set) unless ``ends`` gives its condition."""
    ends = {"inlet": Given(), "outlet": Given(), **(ends or {})}
    return fluid.setup(FluidSetup(geometry or Planar(), length, radius, nz, nr, ends=ends, **options))


def given(fluid, p_in=0.0, p_out=0.0):
    """Set the pressures of the ends of a fluid set up by :func:`setup_fluid` for the next steps."""
    ends = fluid.discrete.ends.conditions
    ends["inlet"].pressure, ends["outlet"].pressure = p_in, p_out


def fluid_step(fluid, state, dt, eta=None, v=None, p_in=0.0, p_out=0.0, robin_mass=None, scheme=BE):
    """A step on the domain of ``eta`` moved by the wall velocity ``v`` (kinematically coupled scheme's A2).

    With ``robin_mass`` M the wall's u_r rows carry (α₀/β₀)M/Δt (v̄ − …), the thin
    layer's inertia with old velocity ``v``.  Returns (new state, energy terms).
    """
    n = fluid.line.ndofs
    eta = np.zeros(n) if eta is None else eta
    v = np.zeros_like(eta) if v is None else v
    interface = None
    if robin_mass is not None:
        interface = Interface((scheme.inertia / dt) * robin_mass, -(robin_mass @ scheme.history([v])) / dt)
    given(fluid, p_in, p_out)
    solution, terms = fluid.step([state], Domain(eta, v), scheme, dt, (0.0, dt), interface, eta, eta + dt * v)
    return solution.state, terms
