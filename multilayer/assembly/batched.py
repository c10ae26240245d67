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
"""

from __future__ import annotations

import numpy as np
import skfem
from skfem.assembly.form.form import FormExtraParams

#: Elements per chunk: bounds the memory of the (elements × points × jets × functions) arrays.
CHUNK = 4096


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
    """Assemble bilinear forms on (trial ``ubasis``, test ``vbasis``) through their kernels.

    :meth:`kernel` evaluates a form's K at every quadrature point; kernels
    of one pair of bases add up, so a sum of terms costs one contraction
    (:meth:`matrix_data`).  The element matrices are flattened in the order
    of :attr:`rows` and :attr:`cols` (test i, trial j, element e).

    >>> from skfem import BilinearForm, ElementTriP2, ElementVector, MeshTri, asm
    >>> import scipy.sparse as sp
    >>> basis = skfem.Basis(MeshTri().refined(1), ElementVector(ElementTriP2()))
    >>> form = BilinearForm(lambda u, v, w: w.x[0] * (u.grad[0][1] * v.grad[1][0] + u[0] * v[1]))
    >>> b = BatchedForm(basis)
    >>> A = sp.coo_matrix((b.data(form), (b.rows, b.cols))).tocsr()
    >>> bool(abs(A - asm(form, basis)).max() < 1e-14)
    True
    """

    def __init__(self, ubasis: skfem.CellBasis, vbasis: skfem.CellBasis | None = None):
        vbasis = ubasis if vbasis is None else vbasis
        self.nelems = ubasis.nelems
        self.dx = ubasis.dx
        self.x = np.asarray(ubasis.global_coordinates())
        self._xi_u = jets(ubasis)
        f = ubasis.basis[0][0]
        self._vshape, self._gshape = np.shape(f)[:-2], np.shape(f.grad)[:-2]
        xi_v = jets(vbasis)
        ne, nq, nv, ni = xi_v.shape
        self._xi_v_t = xi_v.reshape(ne, nq * nv, ni).transpose(0, 2, 1).copy()  # (e, i, q·jet)
        self._unit_u = unit_jets(ubasis, -4)
        self._unit_v = unit_jets(vbasis, -3)
        self._udofs = ubasis.element_dofs
        self._vdofs = vbasis.element_dofs
        self._nv_dofs = vbasis.N
        nj = ubasis.Nbfun
        self.shape = (ni, nj, self.nelems)
        self.rows = np.broadcast_to(vbasis.element_dofs[:, None, :], self.shape).ravel()
        self.cols = np.broadcast_to(ubasis.element_dofs[None, :, :], self.shape).ravel()

    def kernel(self, form, **w) -> np.ndarray:
        """K (elements, points, test jet, trial jet) of ``form``, weighted by the quadrature (dx)."""
        params = FormExtraParams({k: np.asarray(a) if np.ndim(a) >= 2 else a for k, a in w.items()}, x=self.x)
        K = form.form(self._unit_u, self._unit_v, params)
        nv, nu = self._unit_v.shape[-4], self._unit_u.shape[-3]
        K = np.broadcast_to(K, (nv, nu, *self.dx.shape))
        return np.moveaxis(K, (0, 1), (2, 3)) * self.dx[..., None, None]

    def matrix_data(self, K: np.ndarray) -> np.ndarray:
        """Element matrices Σ_q Ξ_vᵀ K Ξ_u of a (sum of) kernel(s), flattened as :attr:`rows`."""
        out = np.empty((self.nelems, *self.shape[:2]))
        for e0 in range(0, self.nelems, CHUNK):
            cut = slice(e0, min(e0 + CHUNK, self.nelems))
            Y = K[cut] @ self._xi_u[cut]  # (e, q, test jet, j)
            out[cut] = self._xi_v_t[cut] @ Y.reshape(Y.shape[0], -1, Y.shape[-1])
        return out.transpose(1, 2, 0).ravel()

    def apply(self, K: np.ndarray, u: np.ndarray) -> np.ndarray:
        """A u for the matrix A of kernel K, without forming A (a test-space vector)."""
        xi = np.einsum("eqmj,je->eqm", self._xi_u, u[self._udofs])
        y = np.einsum("eqnm,eqm->eqn", K, xi).reshape(self.nelems, -1)
        local = np.einsum("eik,ek->ie", self._xi_v_t, y)
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

    def data(self, form, **w) -> np.ndarray:
        """Element matrices of ``form`` (a ``skfem.BilinearForm``) with extra fields ``w``."""
        return self.matrix_data(self.kernel(form, **w))
