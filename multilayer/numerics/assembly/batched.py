"""Element matrices of a bilinear form, computed through its local kernel on the reference element.

scikit-fem calls a bilinear form once per pair (i, j) of local basis
functions — 144 calls for a P2 vector field, each on arrays of every
element.  Every form here is bilinear in the *jets* of its arguments, the
vector ξ = (values, first derivatives) of a function at a point (6 numbers
for a 2D vector field, 3 for a scalar).  So at each quadrature point

    form(u, q) = ξ_qᵀ K ξ_u,

with a small kernel K (6 × 6 for the velocity block) that holds every
coefficient field.  On an affine mesh a function's jet is ξ = T_e ξ̂, with
ξ̂ its jet on the reference element (values, reference derivatives) and
T_e the element's map of derivatives (∂_k = Σ_i (DF_e⁻¹)_ik ∂̂_i).  The
reference jets Ξ̂ of the local basis are the same on every element, so

    A_e = Σ_q dx_q Ξ̂_qᵀ K̂_q,e Ξ̂_q,        K̂ = T_eᵀ K T_e,

and K̂ is what the form returns when called on unit *reference* jets mapped
by T_e — on the pairs of slots the form can use only
(:meth:`BatchedForm.active`: a mass term's kernel is 2 × 2 of the
velocity's 6 × 6).  The element matrices of a chunk of elements are then
one matrix product, B K̂ with B_(ij),(ab q) = Ξ̂_q,ai Ξ̂_q,bj stacked once —
per pair of vector components, since a component's jets only meet its own
functions, and over the pairs of slots (a, b) some term uses.  The skew
part ½(c(u, v) − c(v, u)) of a form (:class:`SkewPart`) is ½(K − Kᵀ) with
K the form's kernel, which is evaluated once.  No array of the basis jets
of every element is kept: a mesh is held as its maps DF_e⁻¹ (4 numbers an
element) and the weights dx.  The form functions of
:mod:`multilayer_plugins.channel.forms` are used unchanged (they also run
under ``skfem.asm``; a test checks that both give the same matrices).

A sum of terms is assembled chunk by chunk of elements: the kernels of all
terms on a chunk are summed and contracted before the next chunk, so no
array of all elements' kernels is ever formed.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import skfem
from scipy.sparse.csgraph import connected_components
from skfem.assembly.form.form import FormExtraParams

#: Elements per chunk: every array of a chunk (the kernels, 36 numbers per
#: point and element) stays in cache, and no array of the whole mesh is made
#: anew each step (docs/performance.md, "Assembly").
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


def affine_inverse(basis: skfem.CellBasis) -> np.ndarray:
    """DF_e⁻¹ of every element, (dim, dim, elements); a ValueError when the mapping is not affine."""
    inv = np.asarray(basis.mapping.invDF(basis.X, tind=basis.tind))  # (dim, dim, elements, points)
    if not np.allclose(inv, inv[..., :1], rtol=1e-12, atol=0.0):
        raise ValueError(f"batched assembly needs an affine mesh ({type(basis.mapping).__name__}: DF varies "
                         "within an element)")
    return np.ascontiguousarray(inv[..., 0])


def reference_jets(basis: skfem.CellBasis, inverse: np.ndarray) -> np.ndarray:
    """Ξ̂: (jet, point, local function), the jets of the local basis on the reference element.

    A jet is (value components, then derivative components), row-major; the
    reference jets are read off the first element and checked on every
    element (ξ = T_e ξ̂ to 1e-10): a ValueError when the basis is not one
    reference basis mapped affinely.
    """
    DF0 = np.linalg.inv(inverse[:, :, 0].T).T  # DF of element 0: Σ_k DF[k, i] ∂_k = ∂̂_i
    out = []
    for (f,) in basis.basis:
        value, grad = np.asarray(f), np.asarray(f.grad)  # (*vshape, E, q), (*vshape, dim, E, q)
        ref_grad = np.einsum("...kq,ki->...iq", grad[..., 0, :], DF0)
        mapped = np.einsum("...iq,ike->...keq", ref_grad, inverse)
        scale = max(np.abs(value).max(), np.abs(grad).max())
        if (np.abs(value - value[..., :1, :]).max() > 1e-10 * scale
                or np.abs(mapped - grad).max() > 1e-10 * scale):
            raise ValueError(f"batched assembly needs one reference basis on every element; "
                             f"{type(basis.elem).__name__} is not mapped affinely")
        nq = value.shape[-1]
        out.append(np.concatenate([value[..., 0, :].reshape(-1, nq), ref_grad.reshape(-1, nq)]))
    return np.stack(out, axis=-1)


def _components(ref: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The (jet slots, local functions) that meet: a vector field's components, one group for a scalar."""
    n, _, nf = ref.shape
    meets = sp.coo_matrix(np.abs(ref).max(axis=1) > 0.0)
    graph = sp.bmat([[None, meets], [meets.T, None]])
    count, label = connected_components(graph, directed=False)
    groups = [(np.flatnonzero(label[:n] == c), np.flatnonzero(label[n:] == c)) for c in range(count)]
    return [(slots, funcs) for slots, funcs in groups if len(slots) and len(funcs)]


def _unit_jets(basis: skfem.CellBasis, inverse: np.ndarray, trial: bool) -> tuple[np.ndarray, np.ndarray]:
    """(value, grad) of one unit reference jet per slot, mapped by T_e: the form arguments of the kernel.

    The slot axis is −3 for the trial function and −4 for the test function
    (a form's result is (test jet, trial jet, points, elements)); values do
    not depend on the element, derivatives do (grad: (..., 1, elements)).
    """
    f = basis.basis[0][0]
    vshape, gshape = np.shape(f)[:-2], np.shape(f.grad)[:-2]
    nv, ng = int(np.prod(vshape, dtype=int)), int(np.prod(gshape))
    n = nv + ng
    eye = np.eye(n)
    value = np.moveaxis(eye[:nv].T.reshape(n, *vshape), 0, -1)[..., None, None]  # (*vshape, slot, 1, 1)
    unit = eye[nv:].T.reshape(n, *gshape)  # (slot, *vshape, i): a unit reference derivative ∂̂_i
    grad = np.einsum("s...i,ike->...kse", unit, inverse)[..., None, :]  # (*vshape, k, slot, 1, E)
    if trial:
        return value[..., None, :, :, :], grad[..., None, :, :, :]
    return value[..., :, None, :, :], grad[..., :, None, :, :]


def _kind(fields: dict) -> tuple:
    """What a form's active slots can depend on in its fields: their names and the component shapes of the arrays."""
    return tuple(sorted((k, np.shape(a)[:-2] if np.ndim(a) >= 2 else None) for k, a in fields.items()))


def _add(total: np.ndarray, r, c, K: np.ndarray) -> None:
    """total[r, c] += K, in place (positions along the first two axes, each as :func:`_run` gives them)."""
    if isinstance(r, slice) or isinstance(c, slice):
        total[r, c] += K  # at most one index array: it selects along its own axis
    else:
        total[np.ix_(r, c)] += K


def _run(positions: np.ndarray):
    """Sorted ``positions`` as a slice when they are consecutive (a view, not a copy), else as they are."""
    if len(positions) and positions[-1] - positions[0] == len(positions) - 1:
        return slice(int(positions[0]), int(positions[-1]) + 1)
    return positions


class SkewPart:
    """½(form(u, v) − form(v, u)): the skew-symmetric part of a bilinear form on one space, as a term's form.

    Its kernel is ½(K − Kᵀ), K the form's with the transpose swapping test and
    trial jet slots, so :class:`BatchedForm` evaluates the form once on its
    active slots: the skew advection of the fluid step costs the convective
    form's 2 × 4 of the velocity's 6 × 6 slots.
    """

    def __init__(self, form):
        self.form = form


class BatchedForm:
    """Assemble sums of bilinear forms on (trial ``ubasis``, test ``vbasis``) through their reference kernels.

    :meth:`data` evaluates the kernels K̂ of a list of terms ``(scale, form,
    fields)`` chunk by chunk of elements, sums them and contracts the sum
    with the reference jets: one matrix product per pair of components for
    any number of terms.  The element matrices are flattened in the order of
    :attr:`rows` and :attr:`cols` (test i, trial j, element e: an entry's
    values over a chunk of elements are written in one piece).  Both bases
    must live on one affine mesh with one quadrature.

    >>> from skfem import BilinearForm, ElementTriP2, ElementVector, MeshTri, asm
    >>> import scipy.sparse as sp
    >>> basis = skfem.Basis(MeshTri().refined(1), ElementVector(ElementTriP2()))
    >>> form = BilinearForm(lambda u, v, w: w.x[0] * (u.grad[0][1] * v.grad[1][0] + u[0] * v[1]))
    >>> b = BatchedForm(basis)
    >>> A = sp.coo_matrix((b.data([(1.0, form, {})]), (b.rows, b.cols))).tocsr()
    >>> bool(abs(A - asm(form, basis)).max() < 1e-14)
    True
    """

    def __init__(self, ubasis: skfem.CellBasis, vbasis: skfem.CellBasis | None = None, chunk: int = CHUNK):
        vbasis = ubasis if vbasis is None else vbasis
        if vbasis.nelems != ubasis.nelems or not np.array_equal(vbasis.dx, ubasis.dx):
            raise ValueError("the trial and test bases must share the mesh and the quadrature")
        self.nelems = ubasis.nelems
        self.chunk = chunk
        self.dx = ubasis.dx
        # the coordinates of the points, (dim, point, element): as the kernel passes fields to a form
        self._x = np.ascontiguousarray(np.swapaxes(np.asarray(ubasis.global_coordinates()), -1, -2))
        self._dx = np.ascontiguousarray(self.dx.T)
        self._inverse = affine_inverse(ubasis)
        self._ref_u = reference_jets(ubasis, self._inverse)  # (trial jet, point, j)
        self._ref_v = self._ref_u if vbasis is ubasis else reference_jets(vbasis, self._inverse)
        f = ubasis.basis[0][0]
        self._vshape, self._gshape = np.shape(f)[:-2], np.shape(f.grad)[:-2]
        self._unit_u = _unit_jets(ubasis, self._inverse, trial=True)
        self._unit_v = _unit_jets(vbasis, self._inverse, trial=False)
        dim = self._inverse.shape[0]
        mix = np.random.default_rng(1).uniform(-1.5, 1.5, (dim, dim)) + 2.0 * np.eye(dim)  # a full map, invertible
        self._probe = (_unit_jets(ubasis, mix[..., None], trial=True), _unit_jets(vbasis, mix[..., None], trial=False))
        self._active: dict = {}  # (form, kind of fields) → its active (test, trial) slots
        self._udofs = ubasis.element_dofs
        self._vdofs = vbasis.element_dofs
        self._nv_dofs = vbasis.N
        (nu, nq, nj), (nv, ni) = self._ref_u.shape, (self._ref_v.shape[0], self._ref_v.shape[2])
        self._sizes = (nv, nu, nq)
        self._same_space = vbasis is ubasis
        self.shape = (ni, nj, self.nelems)
        # element e's matrix entry (i, j) at [i, j, e]: a chunk's entries (i, j) are one contiguous run
        self.rows = np.broadcast_to(vbasis.element_dofs[:, None, :], self.shape).ravel()
        self.cols = np.broadcast_to(ubasis.element_dofs[None, :, :], self.shape).ravel()
        self._components = (_components(self._ref_v), _components(self._ref_u))
        self._plans: dict = {}  # the contraction of a union of active slots (see _plan)
        self._rows_u = np.ascontiguousarray(self._ref_u.transpose(0, 2, 1))  # jet row s at the points: u_e @ this[s]
        self._udofs_t = np.ascontiguousarray(self._udofs.T)  # (element, j)
        self._gathered = np.empty(self._udofs_t.shape)
        self._scratch: np.ndarray | None = None
        self._slots_made: dict = {}  # see _slots

    def chunks(self):
        """Slices of at most :attr:`chunk` elements covering the mesh."""
        for e0 in range(0, self.nelems, self.chunk):
            yield slice(e0, min(e0 + self.chunk, self.nelems))

    def active(self, form, fields: dict) -> np.ndarray:
        """Which (test, trial) pairs of jet slots ``form``'s kernel can use: a boolean (test slot, trial slot) array.

        Probed once per form and kind of fields: the form is called on one
        point set with every field (and the coordinates) replaced by random
        positive values and the unit jets mapped by a random full matrix, so
        a pair counts as active wherever some mesh and some fields could use
        it.  A mass term then costs its value slots (2 × 2 of the velocity's
        6 × 6), a viscous term its derivative slots.  A :class:`SkewPart`
        uses its form's pairs and their transposes.
        """
        form, skew = self._unwrap(form)
        if skew:
            used = self.active(form, fields)
            return used | used.T
        key = (form, _kind(fields))
        used = self._active.get(key)
        if used is None:
            rng = np.random.default_rng(0)
            nv, nu, nq = self._sizes
            probe = {k: 0.5 + rng.random((*np.shape(a)[:-2], nq, 1)) if np.ndim(a) >= 2
                     else (0.5 + rng.random() if isinstance(a, (int, float, np.number)) else a)
                     for k, a in fields.items()}
            (uv, ug), (vv, vg) = self._probe
            x = 0.5 + rng.random((self._x.shape[0], nq, 1))
            K = np.broadcast_to(form.form(_field(uv, ug), _field(vv, vg), FormExtraParams(probe, x=x)), (nv, nu, nq, 1))
            used = self._active[key] = np.abs(K).max(axis=(2, 3)) > 0.0
        return used

    def _unwrap(self, form) -> tuple:
        """(the form to evaluate, whether its skew part is wanted); a ValueError for a skew part across two spaces."""
        if not isinstance(form, SkewPart):
            return form, False
        if not self._same_space:
            raise ValueError("a SkewPart needs one space for the test and trial functions")
        return form.form, True

    def _plan(self, terms: list[Term]) -> tuple:
        """How the kernel of ``terms`` is laid out and contracted, made once per union of active pairs.

        The kernel is kept on the test slots R and trial slots C some term
        uses, (R, C, point, element).  Per pair of vector components the
        contraction takes only the (test, trial) pairs some term uses: B with
        B_(ij),(p q) = Ξ̂_q,a_p,i Ξ̂_q,b_p,j over the active pairs p = (a_p, b_p)
        — the velocity's cross-component pairs meet through derivatives only
        (4 of 9), the divergence's pressure test function through its value.
        Also the element-matrix entries no pair reaches (zero), and the
        restricted reference jets :meth:`apply` multiplies with.
        """
        nv, nu, nq = self._sizes
        used = np.zeros((nv, nu), dtype=bool)
        for _, form, fields in terms:
            used |= self.active(form, fields)
        key = used.tobytes()
        plan = self._plans.get(key)
        if plan is None:
            R, C = np.flatnonzero(used.any(axis=1)), np.flatnonzero(used.any(axis=0))
            ni, nj = self.shape[:2]
            pairs = []
            for sv, fv in self._components[0]:
                for su, fu in self._components[1]:
                    a, b = np.nonzero(used[np.ix_(sv, su)])
                    if not a.size:
                        continue
                    a, b = sv[a], su[b]
                    rows = ((np.searchsorted(R, a) * len(C) + np.searchsorted(C, b))[:, None] * nq + np.arange(nq))
                    B = np.einsum("pqi,pqj->ijpq", self._ref_v[a][:, :, fv], self._ref_u[b][:, :, fu])
                    pairs.append((rows.ravel(), np.ascontiguousarray(B.reshape(len(fv) * len(fu), -1)),
                                  (fv[:, None] * nj + fu[None, :]).ravel()))
            zero = np.setdiff1d(np.arange(ni * nj), np.concatenate([ij for *_, ij in pairs] or [[]]))
            jets_u = np.ascontiguousarray(self._ref_u[C].reshape(len(C) * nq, nj))  # ξ̂ on C = this @ u_e
            test_v = np.ascontiguousarray(self._ref_v[R].reshape(len(R) * nq, ni).T)  # Ξ̂ᵀ on R, applied to y
            plan = self._plans[key] = (R, C, pairs, zero, jets_u, test_v)
        return plan

    def _slots(self, form, fields: dict, R: np.ndarray, C: np.ndarray):
        """Where ``form``'s kernel goes in a kernel on slots (R, C), once per form, kind of fields and slots.

        (rows, cols, at, at_t): its active test and trial slots, their
        positions in (R, C), and the transposed positions (a skew part's
        −½ Kᵀ); None when the form uses no slot.
        """
        kind = (form, _kind(fields), R.tobytes(), C.tobytes())
        if kind not in self._slots_made:
            used = self.active(form, fields)
            rows, cols = np.flatnonzero(used.any(axis=1)), np.flatnonzero(used.any(axis=0))
            self._slots_made[kind] = (
                (rows, cols, (_run(np.searchsorted(R, rows)), _run(np.searchsorted(C, cols))),
                 (_run(np.searchsorted(R, cols)), _run(np.searchsorted(C, rows))) if self._same_space else None)
                if rows.size and cols.size else None)
        return self._slots_made[kind]

    def kernel(self, terms: list[Term], cut: slice = slice(None), slots: tuple | None = None) -> np.ndarray:
        """Σ scale · K̂ · dx of the terms on elements ``cut``: (test jet, trial jet, point, element).

        On the test and trial slots ``slots`` = (R, C) (sorted; by default
        every slot), which must hold every active slot of the terms.  Each form
        is called on the unit jets of its :meth:`active` slots only and added
        into its block of the kernel; a :class:`SkewPart` is evaluated once and
        added as ½(K − Kᵀ).  The forms are evaluated with points before
        elements (their fields are passed transposed, a copy per chunk and
        field), so every product of a unit jet and a field runs along the
        elements.  The array is a buffer of the form, overwritten by the next
        call.
        """
        nv, nu, nq = self._sizes
        R, C = (np.arange(nv), np.arange(nu)) if slots is None else slots
        ne = len(range(*cut.indices(self.nelems)))
        size = len(R) * len(C) * nq * ne
        if self._scratch is None or self._scratch.size < size:
            self._scratch = np.empty(nv * nu * nq * min(self.chunk, self.nelems))
        total = self._scratch[:size].reshape(len(R), len(C), nq, ne)
        total.fill(0.0)
        uv, ug = self._unit_u
        vv, vg = self._unit_v
        local: dict[int, np.ndarray] = {}  # a field's values on the chunk, points first: once per field

        def on_chunk(a):
            if id(a) not in local:
                local[id(a)] = np.ascontiguousarray(np.swapaxes(np.asarray(a)[..., cut, :], -1, -2))
            return local[id(a)]

        for scale, form, fields in terms:
            form, skew = self._unwrap(form)
            slots_of_form = self._slots(form, fields, R, C)
            if slots_of_form is None:
                continue
            rows, cols, at, at_t = slots_of_form
            u = _field(uv, ug[..., cut]) if cols.size == nu else _field(uv[..., cols, :, :], ug[..., cols, :, cut])
            v = _field(vv, vg[..., cut]) if rows.size == nv else _field(vv[..., rows, :, :, :],
                                                                        vg[..., rows, :, :, cut])
            params = FormExtraParams({k: on_chunk(a) if np.ndim(a) >= 2 else a for k, a in fields.items()},
                                     x=self._x[..., cut])
            K = np.broadcast_to((0.5 * scale if skew else scale) * form.form(u, v, params),
                                (rows.size, cols.size, nq, ne))
            _add(total, *at, K)
            if skew:  # −½ Kᵀ: the form with its arguments swapped
                _add(total, *at_t, -K.swapaxes(0, 1))
        total *= self._dx[:, cut]
        return total

    def data(self, terms: list[Term], out: np.ndarray | None = None) -> np.ndarray:
        """Element matrices Σ_q Ξ̂ᵀ K̂ Ξ̂ of the sum of ``terms``, flattened as :attr:`rows`.

        ``out`` (of :attr:`shape`) is written and returned when given: a caller
        that assembles every step keeps one, so a large mesh does not pay
        fresh pages for a new array each time.
        """
        ni, nj, ne = self.shape
        out = (np.empty(self.shape) if out is None else out).reshape(ni * nj, ne)
        R, C, pairs, zero, _, _ = self._plan(terms)
        out[zero] = 0.0  # the entries of component pairs no term couples (a mass term's u_z, u_r)
        for cut in self.chunks():
            K = self.kernel(terms, cut, (R, C))
            K = K.reshape(-1, K.shape[-1])
            for rows, B, ij in pairs:
                out[ij, cut] = B @ K[rows]  # (ij, element): each entry's run over the chunk written in one piece
        return out.ravel()

    def apply(self, terms: list[Term], u: np.ndarray) -> np.ndarray:
        """A u for the matrix A of the sum of ``terms``, without forming A (a test-space vector)."""
        nq = self._sizes[2]
        R, C, _, _, jets_u, test_v = self._plan(terms)
        ue = u[self._udofs]
        local = np.empty(self._vdofs.shape)
        for cut in self.chunks():
            xi = (jets_u @ ue[:, cut]).reshape(len(C), nq, -1)  # ξ̂ of u on the trial slots C
            y = np.einsum("abqe,bqe->aqe", self.kernel(terms, cut, (R, C)), xi)
            local[:, cut] = test_v @ y.reshape(len(R) * nq, -1)
        return np.bincount(self._vdofs.ravel(), weights=local.ravel(), minlength=self._nv_dofs)

    def trial_jets(self, u: np.ndarray, values_only: bool = False, cut: slice = slice(None)) -> np.ndarray:
        """The jets of the trial-space function with DOFs ``u`` at the quadrature points: (jet, elements, points).

        With ``values_only`` only the value components (the first rows of a
        jet); with ``cut`` only those elements.  Each jet row is one matrix
        product u_e Ξ̂ᵀ written in place (no array of all the reference jets),
        and the derivatives are then mapped by DF_e⁻¹ in place.
        """
        nu, nq, nj = self._ref_u.shape
        nval = int(np.prod(self._vshape, dtype=int))
        m = nval if values_only else nu
        ue = self._udofs_t[cut]
        ue = np.take(u, ue, out=self._gathered[: len(ue)], mode="clip")  # u_e: a buffer of the form ('clip': unbuffered)
        out = np.empty((m, len(ue), nq))
        for slot in range(m):
            np.matmul(ue, self._rows_u[slot], out=out[slot])
        if not values_only:
            dim = self._inverse.shape[0]
            inverse = self._inverse[:, :, cut, None]
            grad = out[nval:].reshape(nval, dim, len(ue), nq)
            reference = np.empty((dim, len(ue), nq))
            for c in range(nval):  # ∂_k = Σ_i (DF⁻¹)_ik ∂̂_i
                reference[...] = grad[c]
                np.multiply(inverse[0, :], reference[0], out=grad[c])
                for i in range(1, dim):
                    grad[c] += inverse[i, :] * reference[i]
        return out

    def field(self, u: np.ndarray, cut: slice = slice(None)) -> Field:
        """The trial-space function with DOFs ``u`` as a form argument (values, ``.grad``) at the quadrature points.

        The same numbers as ``ubasis.interpolate(u)`` (on elements ``cut``), from the reference jets.
        """
        jet = self.trial_jets(u, cut=cut)
        nv = int(np.prod(self._vshape, dtype=int))
        return _field(jet[:nv].reshape(*self._vshape, *jet.shape[1:]), jet[nv:].reshape(*self._gshape, *jet.shape[1:]))
