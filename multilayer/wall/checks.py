"""What a layer hands the core, checked: the object its factory builds, its forms, its essential DOFs.

A layer is foreign code, so what it returns is checked where the core
receives it (:meth:`multilayer.wall.stack.Stack.assemble`, the validator's small
wall, the conformance kit :mod:`multilayer.testing`), and a mistake is
told as what it is — ``damping must be a scipy sparse matrix, got float``,
``mass has shape (14, 14); expected (13, 13) for its space`` — instead of
the error it would cause further on.  Each function returns the list of
what is wrong (empty when nothing is); :class:`LayerError` carries them
with the name of the layer.
"""

from __future__ import annotations

import traceback
from typing import Any

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from multilayer.wall.layer import Layer, LayerMatrices, ThickLayer, ThinLayer

#: The three matrices of :class:`~multilayer.wall.layer.LayerMatrices`.
PARTS = ("mass", "damping", "stiffness")
#: max |A − Aᵀ| allowed, relative to max |A|.
SYMMETRY_TOL = 1e-10
#: Smallest eigenvalue allowed, relative to the largest magnitude: ≥ −PSD_TOL · scale.
PSD_TOL = 1e-10
#: Largest matrix whose eigenvalues :func:`matrix_problems` computes (a dense eigensolve).
MAX_DENSE = 2000


class LayerError(ValueError):
    """A layer returned what the core cannot use; the message names the layer.

    >>> print(LayerError("layers[0] (my-layer)", ["mass has shape (3, 3); expected (4, 4) for its space"]))
    layers[0] (my-layer): mass has shape (3, 3); expected (4, 4) for its space
    """

    def __init__(self, where: str, problems: list[str]):
        self.where, self.problems = where, list(problems)
        super().__init__(f"{where}: " + "; ".join(self.problems))


def raised(exc: BaseException) -> str:
    """An exception from plugin code in one line, with where it was raised.

    >>> try:
    ...     {}["x"]
    ... except KeyError as exc:
    ...     print(raised(exc).split(" (")[0])
    KeyError: 'x'
    """
    frames = traceback.extract_tb(exc.__traceback__)
    where = f" ({frames[-1].filename}, line {frames[-1].lineno})" if frames else ""
    return f"{type(exc).__name__}: {exc}{where}"


def abstract_problem(factory: Any) -> str | None:
    """Why ``factory`` cannot be built when it is a class with unimplemented abstract methods.

    >>> class Empty(ThinLayer):
    ...     pass
    >>> abstract_problem(Empty)
    'Empty does not implement forms (abstract in Layer)'
    """
    missing = sorted(getattr(factory, "__abstractmethods__", ()))
    if not isinstance(factory, type) or not missing:
        return None
    owners = {name: next((base.__name__ for base in reversed(factory.__mro__)
                          if getattr(getattr(base, name, None), "__isabstractmethod__", False)), "?")
              for name in missing}
    return f"{factory.__name__} does not implement " + ", ".join(f"{m} (abstract in {owners[m]})" for m in missing)


def type_problem(layer: Any, thin: bool) -> str | None:
    """Why ``layer`` is not a layer of the kind its plugin record declares (``thin``), or None.

    >>> type_problem({}, True)
    'the factory returned dict; expected a ThinLayer (the plugin is registered with thin=True)'
    """
    expected = ThinLayer if thin else ThickLayer
    if isinstance(layer, expected):
        if not thin:
            h = getattr(layer, "thickness", None)
            if not isinstance(h, int | float) or isinstance(h, bool) or not np.isfinite(h) or h <= 0:
                return f"a thick layer needs a thickness attribute > 0 (cm), got {h!r}"
        return None
    got = type(layer).__name__
    if isinstance(layer, Layer):
        got = f"a {'thin' if layer.thin else 'thick'} layer ({got})"
    return f"the factory returned {got}; expected a {expected.__name__} (the plugin is registered with thin={thin})"


def matrix_problems(matrices: Any, n: int, definite: bool = False) -> list[str]:
    """What is wrong with a layer's ``forms`` output for a space of ``n`` DOFs.

    Each of mass, damping and stiffness must be a scipy sparse matrix of
    shape (n, n) with finite real entries, symmetric to :data:`SYMMETRY_TOL`;
    with ``definite`` also positive semi-definite to :data:`PSD_TOL`
    (eigenvalues of the dense matrix, for n ≤ :data:`MAX_DENSE`).

    >>> I = sp.identity(3, format="csr")
    >>> matrix_problems(LayerMatrices(I, 0.0, I), 3)
    ['damping must be a scipy sparse matrix, got float']
    >>> matrix_problems(LayerMatrices(I, I, -I), 3, definite=True)
    ['stiffness is not positive semi-definite: smallest eigenvalue -1 against a largest magnitude of 1']
    """
    if not isinstance(matrices, LayerMatrices):
        return [f"forms returned {type(matrices).__name__}; expected LayerMatrices(mass, damping, stiffness)"]
    problems = []
    for part in PARTS:
        A = getattr(matrices, part)
        if not sp.issparse(A):
            problems.append(f"{part} must be a scipy sparse matrix, got {type(A).__name__}")
            continue
        if A.shape != (n, n):
            problems.append(f"{part} has shape {A.shape}; expected ({n}, {n}) for its space")
            continue
        A = sp.csr_matrix(A)
        if np.iscomplexobj(A.data) or not np.issubdtype(A.dtype, np.number):
            problems.append(f"{part} must have real entries, got {A.dtype}")
            continue
        if not np.all(np.isfinite(A.data)):
            problems.append(f"{part} has non-finite entries (nan or inf)")
            continue
        scale = float(abs(A).max()) if A.nnz else 0.0
        asymmetry = float(abs(A - A.T).max()) if A.nnz else 0.0
        if asymmetry > SYMMETRY_TOL * scale:
            problems.append(f"{part} is not symmetric: max |A - Aᵀ| = {asymmetry:.3g} against max |A| = {scale:.3g}")
            continue
        if definite and 0 < n <= MAX_DENSE:
            eigenvalues = scipy.linalg.eigvalsh(A.toarray())
            top = float(np.max(np.abs(eigenvalues)))
            if eigenvalues[0] < -PSD_TOL * top:
                problems.append(f"{part} is not positive semi-definite: smallest eigenvalue {eigenvalues[0]:.3g} "
                                f"against a largest magnitude of {top:.3g}")
    return problems


def essential_problems(dofs: Any, n: int) -> list[str]:
    """What is wrong with a layer's ``essential_dofs`` for a space of ``n`` DOFs: integers in 0..n−1.

    >>> essential_problems([0.0, 4.0], 5), essential_problems([0, 7], 5)
    (['essential_dofs must be integers, got float64'], ['essential_dofs has indices outside 0..4: [7]'])
    """
    try:
        array = np.asarray(dofs)
    except Exception as exc:  # foreign data: say what it is
        return [f"essential_dofs must be an array of DOF indices, got {type(dofs).__name__} ({exc})"]
    if array.ndim != 1:
        return [f"essential_dofs must be a 1-D array of DOF indices, got shape {array.shape}"]
    if array.size == 0:
        return []
    if not np.issubdtype(array.dtype, np.integer):
        return [f"essential_dofs must be integers, got {array.dtype}"]
    outside = array[(array < 0) | (array >= n)]
    if outside.size:
        return [f"essential_dofs has indices outside 0..{n - 1}: {outside[:5].tolist()}"]
    return []


def linearity_problem(layer: Any, matrices: Any) -> str | None:
    """Why ``layer``'s declaration ``linear`` does not match the forms it returned (None when it does).

    >>> from multilayer.wall.layer import NonlinearForms
    >>> I = sp.identity(2, format="csr")
    >>> class Curved(ThinLayer):
    ...     def forms(self, space):
    ...         return NonlinearForms(I, I, I)
    >>> linearity_problem(Curved(), NonlinearForms(I, I, I))
    'forms returned nonlinear forms (NonlinearForms), but the layer declares linear = True; set linear = False on its class'
    """
    if not isinstance(matrices, LayerMatrices) or matrices.linear == bool(getattr(layer, "linear", True)):
        return None
    if matrices.linear:
        return (f"forms returned linear forms ({type(matrices).__name__}), but the layer declares linear = False; "
                "return NonlinearForms, or leave linear at True")
    return (f"forms returned nonlinear forms ({type(matrices).__name__}), but the layer declares linear = True; "
            "set linear = False on its class")


def state_problems(forms: LayerMatrices, n: int, d: np.ndarray | None = None,
                   v: np.ndarray | None = None) -> list[str]:
    """What is wrong with what nonlinear ``forms`` return at the state (d, v) (default: at rest) on ``n`` DOFs.

    ``elastic`` a finite number, ``force`` and ``damping_force`` finite real arrays of shape (n,),
    ``tangent`` and ``damping_tangent`` scipy sparse (n, n) with finite entries.

    >>> from multilayer.wall.layer import NonlinearForms
    >>> I = sp.identity(2, format="csr")
    >>> class Bad(NonlinearForms):
    ...     def force(self, d):
    ...         return np.full(3, np.nan)
    >>> state_problems(Bad(I, I, I), 2)
    ['force returned an array of shape (3,); expected (2,)']
    """
    d = np.zeros(n) if d is None else d
    v = np.zeros(n) if v is None else v
    problems = []
    for name, arg in (("elastic", d), ("force", d), ("tangent", d), ("damping_force", v), ("damping_tangent", v)):
        try:
            out = getattr(forms, name)(arg)
        except Exception as exc:  # the layer's own code
            problems.append(f"{name} raised {raised(exc)}")
            continue
        if name == "elastic":
            if not isinstance(out, int | float | np.floating) or not np.isfinite(out):
                problems.append(f"elastic must return a finite number, got {out!r}")
        elif name.endswith("tangent"):
            if not sp.issparse(out) or out.shape != (n, n):
                shape = getattr(out, "shape", None)
                problems.append(f"{name} must return a scipy sparse matrix of shape ({n}, {n}), got "
                                f"{type(out).__name__} of shape {shape}")
            elif not np.all(np.isfinite(sp.csr_matrix(out).data)):
                problems.append(f"{name} has non-finite entries (nan or inf)")
        else:
            out = np.asarray(out)
            if out.shape != (n,):
                problems.append(f"{name} returned an array of shape {out.shape}; expected ({n},)")
            elif not np.issubdtype(out.dtype, np.floating) or not np.all(np.isfinite(out)):
                problems.append(f"{name} must return finite real numbers")
    return problems
