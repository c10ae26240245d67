"""Convergence acceleration of a fixed-point interface iteration x = H(x).

A sub-iterated partitioned coupler solves for the interface unknown x (the
wall velocity on Γ) with x̃ = H(x) one fluid solve then one wall solve, and
the residual r = x̃ − x.  Plain iteration diverges when the wall is light
(the added-mass effect); these update x from the history of (x, x̃, r):

* :class:`Aitken` — dynamic relaxation x ← x + ω r, with ω from the last two
  residuals (Küttler & Wall 2008);
* :class:`IQNILS` — interface quasi-Newton with an inverse Jacobian from a
  least-squares fit of the residual and output differences, reusing the
  differences of the last ``reuse`` time steps (Degroote, Bathe & Vierendeels
  2009; what preCICE and CoCoNuT call IQN-ILS).

Both take :meth:`start` at each time step and :meth:`next` per iteration;
what they carry from one time step to the next is :meth:`memory`, a value
a coupler keeps in its state (so a resumed run goes on exactly) and hands
back with :meth:`recall`.

>>> import numpy as np
>>> A = np.array([[-3.0, 0.5], [0.5, -1.0]]); b = np.array([1.0, 2.0])
>>> H = lambda x: A @ x + b   # like the added mass: an eigenvalue < −1, plain iteration diverges
>>> for method in (Aitken(0.5), IQNILS(0.5)):
...     method.start(); x = np.zeros(2)
...     for k in range(50):
...         r = H(x) - x
...         if np.linalg.norm(r) < 1e-12: break
...         x = method.next(x, H(x), r)
...     print(type(method).__name__, k, np.allclose(x, np.linalg.solve(np.eye(2) - A, b)))
Aitken 8 True
IQNILS 3 True
"""

from __future__ import annotations

from collections import deque

import numpy as np


class Aitken:
    """Aitken's dynamic relaxation.

    Parameters
    ----------
    omega0 : float
        The relaxation of each step's first iteration (and the cap |ω| ≤ ``omega_max``).
    """

    def __init__(self, omega0: float = 0.5, omega_max: float = 1.0):
        self.omega0, self.omega_max = omega0, omega_max
        self.omega = omega0
        self._r_old: np.ndarray | None = None

    def memory(self) -> float:
        """What the next time step starts from: the last ω."""
        return self.omega

    def recall(self, memory: float | None) -> None:
        if memory is not None:
            self.omega = float(memory)

    def start(self) -> None:
        """A new time step: forget the last residual; start from the last step's ω (at most ω₀ in size)."""
        self.omega = float(np.sign(self.omega) * min(abs(self.omega), self.omega0)) or self.omega0
        self._r_old = None

    def next(self, x: np.ndarray, x_tilde: np.ndarray, r: np.ndarray) -> np.ndarray:
        if self._r_old is not None:
            dr = r - self._r_old
            denominator = float(dr @ dr)
            if denominator > 0.0:
                self.omega = float(np.clip(-self.omega * (self._r_old @ dr) / denominator,
                                           -self.omega_max, self.omega_max))
        self._r_old = r.copy()
        return x + self.omega * r


class IQNILS:
    """Interface quasi-Newton, inverse Jacobian by least squares (IQN-ILS).

    Parameters
    ----------
    omega0 : float
        Relaxation of the first iteration when there is no history yet.
    reuse : int
        Time steps whose differences are kept for the next steps (0: this step's only).
    rcond : float
        Columns whose contribution falls below this relative size are dropped (a QR filter
        in spirit: near-dependent differences would make the fit ill-posed).
    """

    def __init__(self, omega0: float = 0.5, reuse: int = 8, rcond: float = 1e-10):
        self.omega0, self.reuse, self.rcond = omega0, reuse, rcond
        self._past: deque[tuple[list, list]] = deque(maxlen=max(reuse, 0) or None)
        self._V: list[np.ndarray] = []
        self._W: list[np.ndarray] = []
        self._last: tuple[np.ndarray, np.ndarray] | None = None

    def memory(self) -> tuple:
        """The differences of the steps to be reused, with this step's (as :meth:`start` will file them)."""
        past = list(self._past)
        if self._V and self.reuse > 0:
            past = (past + [(self._V, self._W)])[-self.reuse:]
        return tuple((tuple(V), tuple(W)) for V, W in past)

    def recall(self, memory: tuple | None) -> None:
        if memory is not None:
            self._past.clear()
            self._past.extend((list(V), list(W)) for V, W in memory)
            self._V, self._W, self._last = [], [], None

    def start(self) -> None:
        """A new time step: file this step's differences among the reused ones."""
        if self._V and self.reuse > 0:
            self._past.append((self._V, self._W))
        self._V, self._W, self._last = [], [], None

    def next(self, x: np.ndarray, x_tilde: np.ndarray, r: np.ndarray) -> np.ndarray:
        if self._last is not None:
            r_old, x_tilde_old = self._last
            self._V.insert(0, r - r_old)
            self._W.insert(0, x_tilde - x_tilde_old)
        self._last = (r.copy(), x_tilde.copy())
        V = self._V + [v for past_V, _ in reversed(self._past) for v in past_V]
        W = self._W + [w for _, past_W in reversed(self._past) for w in past_W]
        if not V:
            return x + self.omega0 * r
        V_mat, W_mat = np.column_stack(V), np.column_stack(W)
        c, *_ = np.linalg.lstsq(V_mat, -r, rcond=self.rcond)
        return x_tilde + W_mat @ c
