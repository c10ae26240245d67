"""The terms of theory §6 step A2 as scikit-fem forms on the reference channel.

Every form is written on Ω̂ with the ALE coefficient fields of
:class:`multilayer_plugins.channel.ale.ALEFields` passed as ``w`` arguments (``J``,
``gz``, ``gr``, and ``dJdt`` / ``a`` where a term needs them), and without
its physical constant: the step multiplies ``mass_J`` by ρ_f/Δt,
``advection_skew`` by ρ_f (assembled as the skew part of ``advection``),
``moving_domain`` by ρ_f, ``viscous`` by 2μ, and the ``dynamic_pressure``
load by P_in or P_out.

The forms use component indexing and elementwise arithmetic only (no
einsum), so that :class:`multilayer.numerics.assembly.batched.BatchedForm` can call
them on all pairs of basis functions at once; ``skfem.asm`` works too.
Coefficients multiply one factor before the product (``dot(J u, q)``, not
``J dot(u, q)``): batched, the factors are per function, the product per pair.

In a tube (a geometry with radial power k = 1, theory §11) the strain rate
has the hoop entry D_θθ = u_r/r and the divergence the term u_r/r: the step
adds ``hoop_viscous`` (× 2μk) to ``viscous`` and ``hoop_divergence`` (× k)
to ``pressure_divergence``, with the field ``hoop`` = 1/r; ``J`` is then the
volume factor J² of the ALE map.

The functionals at the end are the integrands of the A2 energy identity
(theory §7); the ledger evaluates them with the quadrature of the assembly.
"""

from __future__ import annotations

from skfem import BilinearForm, Functional, LinearForm


def dot(a, b):
    """a·b of two 2-vectors (component axis first)."""
    return a[0] * b[0] + a[1] * b[1]


def ddot(A, B):
    """A:B of two symmetric 2×2 tensors (component axes first).

    The 2 of the off-diagonal pair multiplies A's entry before the product
    (exact either way): batched, A is one function's, the product every pair's.
    """
    return A[0][0] * B[0][0] + (2.0 * A[0][1]) * B[0][1] + A[1][1] * B[1][1]


def grad_eta(u, w) -> tuple:
    """∇^η u on Ω̂ for a vector field u = (u_z, u_r): entry [i][j] is ∂_j u_i, j ∈ (z, r).

    Nested tuples of the four entries (no array of them is stacked: in the
    batched assembly each entry is a kernel-sized array, and a stacked copy
    of the four would be the most of a form's cost).

    Under an axial mesh motion (``gzz``, ``grz`` among the fields) every
    entry of F⁻¹ enters: ∂_z = g_zz ∂_ẑ + g_z ∂_r̂, ∂_r = g_rz ∂_ẑ + g_r ∂_r̂.
    """
    G = u.grad
    if getattr(w, "gzz", None) is not None:
        return ((w.gzz * G[0][0] + w.gz * G[0][1], w.grz * G[0][0] + w.gr * G[0][1]),
                (w.gzz * G[1][0] + w.gz * G[1][1], w.grz * G[1][0] + w.gr * G[1][1]))
    return ((G[0][0] + w.gz * G[0][1], w.gr * G[0][1]),
            (G[1][0] + w.gz * G[1][1], w.gr * G[1][1]))


def sym(G) -> tuple:
    """The symmetric part ½(G + Gᵀ): D^η(u) when G = ∇^η u."""
    off = 0.5 * (G[0][1] + G[1][0])
    return ((G[0][0], off), (off, G[1][1]))


def scaled(c, A) -> tuple:
    """c A for a coefficient field c and a 2 × 2 tensor A (nested tuples)."""
    return ((c * A[0][0], c * A[0][1]), (c * A[1][0], c * A[1][1]))


def transport(a, G) -> tuple:
    """(a·∇^η)u for G = ∇^η u: component i is Σ_j a_j ∂_j u_i."""
    return (a[0] * G[0][0] + a[1] * G[0][1], a[0] * G[1][0] + a[1] * G[1][1])


@BilinearForm
def mass_J(u, q, w):
    """∫ J u·q  (× ρ_f/Δt: the backward-Euler inertia on the domain of ηⁿ)."""
    return dot(w.J * u, q)


@BilinearForm
def advection(u, q, w):
    """∫ J ((a·∇^η)u)·q, a = uⁿ − w: the convective form, whose skew-symmetric part the step assembles.

    The step hands :class:`~multilayer.numerics.assembly.batched.SkewPart` of this form
    to the batched assembly, which evaluates it once on its 2 × 4 active jet
    slots and adds ½(K − Kᵀ): the kernel of ``advection_skew``.
    """
    t = transport(w.a, grad_eta(u, w))
    return dot((w.J * t[0], w.J * t[1]), q)


@BilinearForm
def advection_skew(u, q, w):
    """∫ J [½((a·∇^η)u)·q − ½((a·∇^η)q)·u], a = uⁿ − w  (× ρ_f): ½(advection(u, q) − advection(q, u)).

    Skew-symmetric: it vanishes for q = u, which is what makes the ledger close.
    """
    return 0.5 * (advection.form(u, q, w) - advection.form(q, u, w))


@BilinearForm
def moving_domain(u, q, w):
    """½ ∫ ∂_t J u·q with ∂_t J = v^{n+½}/R  (× ρ_f); Stokes keeps it too."""
    return dot((0.5 * w.dJdt) * u, q)


@BilinearForm
def viscous(u, q, w):
    """∫ J D^η(u):D^η(q)  (× 2μ)."""
    return ddot(scaled(w.J, sym(grad_eta(u, w))), sym(grad_eta(q, w)))


@BilinearForm
def pressure_divergence(u, pi, w):
    """∫ J π ∇^η·u: the constraint row; its transpose, negated, is −∫ J p ∇^η·q."""
    G = grad_eta(u, w)
    return (w.J * (G[0][0] + G[1][1])) * pi


@BilinearForm
def hoop_viscous(u, q, w):
    """∫ J (u_r/r)(q_r/r)  (× 2μk): the hoop product D_θθ(u) D_θθ(q) of a tube's viscous form."""
    return (w.J * w.hoop * u[1]) * (w.hoop * q[1])


@BilinearForm
def hoop_divergence(u, pi, w):
    """∫ J π u_r/r  (× k): the hoop part of a tube's divergence ∂_z u_z + ∂_r u_r + u_r/r."""
    return (w.J * w.hoop * u[1]) * pi


@LinearForm
def dynamic_pressure(q, w):
    """−∫ J q·n on an inlet or outlet facet set (× P): P_in ∫_Γin q_z, −P_out ∫_Γout q_z.

    J is the stretch (R + η)/R of the end, so the integral is over the
    physical segment 0 < r < R + η.
    """
    return -w.J * dot(q, w.n)


@Functional
def kinetic(w):
    """½ ∫ J |u|²  (× ρ_f)."""
    return 0.5 * w.J * dot(w.u, w.u)


@Functional
def strain_squared(w):
    """∫ J |D^η(u)|²  (× 2μΔt: the viscous dissipation of a step)."""
    D = sym(grad_eta(w.u, w))
    return w.J * ddot(D, D)


@Functional
def hoop_squared(w):
    """∫ J (u_r/r)²  (× 2μkΔt: the hoop part of a tube's viscous dissipation)."""
    return w.J * (w.hoop * w.u[1]) ** 2


@Functional
def normal_flux(w):
    """∫ J u·n over a facet set: the volume flux out through it (cm²/s in 2D)."""
    return w.J * dot(w.u, w.n)
