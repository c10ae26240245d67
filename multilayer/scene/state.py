"""The state of a run at one time level, as a value.

A coupler takes a :class:`State` and yields new ones; nothing in a state
is mutated.  A multistep scheme reaches older levels through
:attr:`State.previous` (a chain kept only as long as the scheme needs).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import attrs
import numpy as np


@attrs.frozen(eq=False)
class WallState:
    """Wall displacement d and velocity V, in the wall's numbering."""

    d: np.ndarray
    V: np.ndarray


@attrs.frozen(eq=False)
class State:
    """Everything a scheme needs at tⁿ.

    Attributes
    ----------
    n, t : int, float
        Step number and time (s).
    wall : WallState or None
        The whole wall (every layer, every line and band).
    fluid : object or None
        The fluid's own state value (for the channel fluid: u, p, v).
    v : ndarray or None
        Velocity of the thin layer on the fluid interface line, when a fluid
        carries it (the kinematic condition u = v e_r on Γ); it may differ
        from the wall's V there in a partitioned scheme.
    eta : ndarray or None
        η of the fluid's domain, on the fluid's interface line.
    extra : mapping
        What else a scheme carries from step to step (e.g. the interface traction).
    previous : State or None
        The state one step earlier, for multistep schemes and extrapolation.
    """

    n: int
    t: float
    wall: WallState | None = None
    fluid: Any = None
    v: np.ndarray | None = None
    eta: np.ndarray | None = None
    extra: Mapping[str, np.ndarray] = attrs.field(factory=dict)
    previous: State | None = None

    def history(self, levels: int) -> list[State]:
        """[self, previous, ...]: ``levels`` states, the oldest repeated when the chain is shorter.

        Repeating the oldest level means the solution was at rest before t = 0.
        """
        out: list[State] = [self]
        while len(out) < levels:
            out.append(out[-1].previous or out[-1])
        return out

    def then(self, keep: int, **changes: Any) -> State:
        """The next state: ``changes`` applied, ``self`` as its previous, the chain cut to ``keep`` older levels."""
        return attrs.evolve(self, previous=self.trimmed(keep - 1) if keep > 0 else None, **changes)

    def trimmed(self, keep: int) -> State:
        """This state with at most ``keep`` older levels behind it."""
        previous = self.previous.trimmed(keep - 1) if keep > 0 and self.previous is not None else None
        return attrs.evolve(self, previous=previous)
