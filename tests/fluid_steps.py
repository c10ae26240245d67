"""One fluid step as the couplers take it, for the fluid's own tests."""

import numpy as np

from multilayer.fluid.contract import Domain, Interface
from multilayer.numerics.timescheme import SCHEMES

BE = SCHEMES["backward-euler"]


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
    solution, terms = fluid.step([state], Domain(eta, v), scheme, dt, p_in, p_out, interface, eta, eta + dt * v)
    return solution.state, terms
