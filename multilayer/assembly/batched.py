"""Element matrices of a bilinear form, computed through its local kernel.

scikit-fem calls a bilinear form once per pair (i, j) of local basis
functions — 144 calls for a P2 vector field, each on arrays of every
element.  Every form here is bilinear in the *jets* of its arguments, the
vector ξ = (values, first derivatives) of a function at a point (6 numbers
for a 2D vector field, 3 for a scalar).  So at each quadrature point

    form(u, q) = ξ_qᵀ K ξ_u,

with a small kernel K (6 × 6 for the velocity block) that holds every
coefficient field.  K is obtained by calling the form once on unit jets;
the element matrices are then A_e = Σ_q dx_q Ξ_q,eᵀ K_q,e Ξ_u,e, two
batched matrix products with the jets Ξ of the reference basis, stacked
once at setup.  The form functions of :mod:`multilayer_plugins.channel.forms` are
used unchanged (they also run under ``skfem.asm``; a test checks that both
give the same matrices).

A sum of terms is assembled chunk by chunk of elements: the kernels of all
terms on a chunk are summed and contracted before the next chunk, so no
array of all elements' kernels is ever formed (their size, not the
arithmetic, is what made one pass slow on large meshes).
"""

from __future__ import annotations

import numpy as np
import skfem
from skfem.assembly.form.form import FormExtraParams

#: Elements per chunk: every array of a chunk (the kernels, 36 numbers per
#: point and element) stays in cache, and no array of the whole mesh is made
#: anew each step (docs/performance.md, "Assembly: constant, geometry, state").
CHUNK = 1024

#: A term of a sum of forms: (scale, form, fields) — ``scale · form`` with the coefficient fields ``fields``.
Term = tuple


class Field(np.ndarray):
    """Values with gradients as ``.grad``, what a form receives for u and q."""

    grad = None


def _field(value: np.ndarray, grad: np.ndarray) -> Field:
    field = value.view(Field)
    field.grad = grad
    return field


def jets(basis: skfem.CellBasis) -> np.ndarray:
    """Ξ: (elements, points, jet, local function) for every local basis function.

    A jet is (value components, then gradient components), row-major.
    """
    per_function = []
    for (f,) in basis.basis:
        value, grad = np.asarray(f), np.asarray(f.grad)
        lead = value.ndim - 2
        parts = [value.reshape(-1, *value.shape[lead:]), grad.reshape(-1, *grad.shape[-2:])]
        per_function.append(np.concatenate(parts))  # (jet, elements, points)
    return np.stack(per_function, axis=-1).transpose(1, 2, 0, 3).copy()


def unit_jets(basis: skfem.CellBasis, axis: int) -> Field:
    """One unit jet per slot of the basis' jet, stacked on ``axis`` (−4 trial, −3 test)."""
    f = basis.basis[0][0]
    vshape, gshape = np.shape(f)[:-2], np.shape(f.grad)[:-2]
    nv, ng = int(np.prod(vshape, dtype=int)), int(np.prod(gshape))
    n = nv + ng
    eye = np.eye(n)
    value = eye[:nv].T.reshape(n, *vshape)  # (jet, *vshape)
    grad = eye[nv:].T.reshape(n, *gshape)
    value = np.moveaxis(value, 0, -1)[..., None, None]  # (*vshape, jet, 1, 1)
    grad = np.moveaxis(grad, 0, -1)[..., None, None]
    if axis == -4:
        value, grad = value[..., None, :, :, :], grad[..., None, :, :, :]
    else:
        value, grad = value[..., :, None, :, :], grad[..., :, None, :, :]
    return _field(value, grad)


class BatchedForm:
    """Assemble sums of bilinear forms on (trial ``ubasis``, test ``vbasis``) through their kernels.

    :meth:`data` evaluates the kernels K of a list of terms ``(scale, form,
    fields)`` chunk by chunk of elements, sums them and contracts the sum
    with the basis jets: one contraction for any number of terms.  The
    element matrices are flattened in the order of :attr:`rows` and
    :attr:`cols` (element e, test i, trial j).  The jets of a basis are
    stacked once; ``jets_u`` shares them with another form on the same
    trial basis.

    >>> from skfem import BilinearForm, ElementTriP2, ElementVector, MeshTri, asm
    >>> import scipy.sparse as sp
    >>> basis = skfem.Basis(MeshTri().refined(1), ElementVector(ElementTriP2()))
    >>> form = BilinearForm(lambda u, v, w: w.x[0] * (u.grad[0][1] * v.grad[1][0] + u[0] * v[1]))
    >>> b = BatchedForm(basis)
    >>> A = sp.coo_matrix((b.data([(1.0, form, {})]), (b.rows, b.cols))).tocsr()
    >>> bool(abs(A - asm(form, basis)).max() < 1e-14)
    True
    """

    def __init__(self, ubasis: skfem.CellBasis, vbasis: skfem.CellBasis | None = None,
                 jets_u: np.ndarray | None = None, chunk: int = CHUNK):
        same = vbasis is None or vbasis is ubasis
        vbasis = ubasis if vbasis is None else vbasis
        self.nelems = ubasis.nelems
        self.chunk = chunk
        self.dx = ubasis.dx
        self.x = np.asarray(ubasis.global_coordinates())
        self._xi_u = jets(ubasis) if jets_u is None else jets_u
        self._xi_v = self._xi_u if same else jets(vbasis)
        f = ubasis.basis[0][0]
        self._vshape, self._gshape = np.shape(f)[:-2], np.shape(f.grad)[:-2]
        self._unit_u = unit_jets(ubasis, -4)
        self._unit_v = unit_jets(vbasis, -3)
        self._udofs = ubasis.element_dofs
        self._vdofs = vbasis.element_dofs
        self._nv_dofs = vbasis.N
        ni, nj = vbasis.Nbfun, ubasis.Nbfun
        self.shape = (self.nelems, ni, nj)
        self.rows = np.broadcast_to(vbasis.element_dofs.T[:, :, None], self.shape).ravel()
        self.cols = np.broadcast_to(ubasis.element_dofs.T[:, None, :], self.shape).ravel()

    @property
    def jets(self) -> np.ndarray:
        """Ξ_u, the trial basis' jets (elements, points, jet, function): to share with another form."""
        return self._xi_u

    def _chunks(self):
        for e0 in range(0, self.nelems, self.chunk):
            yield slice(e0, min(e0 + self.chunk, self.nelems))

    def kernel(self, terms: list[Term], cut: slice = slice(None)) -> np.ndarray:
        """Σ scale · K (elements, points, test jet, trial jet) of the terms on elements ``cut``, times dx."""
        x = self.x[:, cut]
        total = None
        for scale, form, fields in terms:
            params = FormExtraParams({k: np.asarray(a)[..., cut, :] if np.ndim(a) >= 2 else a
                                      for k, a in fields.items()}, x=x)
            K = form.form(self._unit_u, self._unit_v, params)
            total = scale * K if total is None else total + scale * K
        nv, nu = self._unit_v.shape[-4], self._unit_u.shape[-3]
        total = np.broadcast_to(total, (nv, nu, *x.shape[1:]))
        return np.moveaxis(total, (0, 1), (2, 3)) * self.dx[cut, :, None, None]

    def data(self, terms: list[Term], out: np.ndarray | None = None) -> np.ndarray:
        """Element matrices Σ_q Ξ_vᵀ K Ξ_u of the sum of ``terms``, flattened as :attr:`rows`.

        ``out`` (of :attr:`shape`) is written and returned when given: a caller
        that assembles every step keeps one, so a large mesh does not pay
        fresh pages for a new array each time.
        """
        out = np.empty(self.shape) if out is None else out
        for cut in self._chunks():
            Y = self.kernel(terms, cut) @ self._xi_u[cut]  # (e, q, test jet, j)
            ne, nq, nv, nj = Y.shape
            Xv = self._xi_v[cut].reshape(ne, nq * nv, -1)
            out[cut] = Xv.transpose(0, 2, 1) @ Y.reshape(ne, nq * nv, nj)
        return out.ravel()

    def apply(self, terms: list[Term], u: np.ndarray) -> np.ndarray:
        """A u for the matrix A of the sum of ``terms``, without forming A (a test-space vector)."""
        local = np.empty(self._vdofs.shape)
        for cut in self._chunks():
            xi = np.einsum("eqmj,je->eqm", self._xi_u[cut], u[self._udofs[:, cut]])
            y = np.einsum("eqnm,eqm->eqn", self.kernel(terms, cut), xi)
            local[:, cut] = np.einsum("eqni,eqn->ie", self._xi_v[cut], y)
        return np.bincount(self._vdofs.ravel(), weights=local.ravel(), minlength=self._nv_dofs)

    def trial_jets(self, u: np.ndarray, values_only: bool = False) -> np.ndarray:
        """The jets of the trial-space function with DOFs ``u`` at every quadrature point: (jet, elements, points).

        With ``values_only`` only the value components (the first rows of a jet).
        """
        xi = self._xi_u[:, :, : int(np.prod(self._vshape, dtype=int))] if values_only else self._xi_u
        return np.einsum("eqmj,je->meq", xi, u[self._udofs])

    def field(self, u: np.ndarray) -> Field:
        """The trial-space function with DOFs ``u`` as a form argument (values, ``.grad``) at the quadrature points.

        The same numbers as ``ubasis.interpolate(u)``, from the jets stacked at setup.
        """
        jet = self.trial_jets(u)
        nv = int(np.prod(self._vshape, dtype=int))
        return _field(jet[:nv].reshape(*self._vshape, *jet.shape[1:]), jet[nv:].reshape(*self._gshape, *jet.shape[1:]))
