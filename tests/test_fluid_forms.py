"""The A2 forms, the ALE fields and the batched assembly (multilayer_plugins.channel)."""

import doctest

import numpy as np
import pytest
import scipy.sparse as sp
import skfem
from skfem import asm

import multilayer.numerics.assembly.batched
import multilayer.numerics.assembly.pattern
import multilayer_plugins.channel.ale
import multilayer_plugins.channel.channel
import multilayer_plugins.channel.model
from multilayer.numerics.assembly.batched import BatchedForm, SkewPart
from multilayer_plugins.channel import forms
from multilayer_plugins.channel.ale import ALEFields
from multilayer_plugins.channel.channel import Channel
from multilayer_plugins.planar import Planar


@pytest.mark.parametrize(
    "module",
    [
        multilayer_plugins.channel.ale,
        multilayer.numerics.assembly.batched,
        multilayer_plugins.channel.channel,
        multilayer_plugins.channel.model,
        multilayer.numerics.assembly.pattern,
    ],
)
def test_doctests(module):
    assert doctest.testmod(module).failed == 0


def deformed(order):
    ch = Channel.build(Planar(), 2.0, 0.5, nz=4, nr=3, order=order, grading=1.5)
    z = ch.line.z
    eta = 0.1 * np.sin(np.pi * z / 2.0) * (1.0 + z)
    v = 0.3 * np.sin(2.0 * np.pi * z / 2.0)
    return ch, ALEFields.at(ch, eta, v)


@pytest.mark.parametrize("order", [1, 2])
def test_batched_assembly_equals_scikit_fem(order):
    ch, f = deformed(order)
    kw = f.forms_kwargs()
    a = np.stack([np.cos(ch.rhat), f.wr])
    cases = [
        (forms.mass_J, (ch.velocity,), kw),
        (forms.viscous, (ch.velocity,), kw),
        (forms.moving_domain, (ch.velocity,), {"dJdt": f.dJdt}),
        (forms.advection_skew, (ch.velocity,), dict(kw, a=a)),
        (SkewPart(forms.advection), (ch.velocity,), dict(kw, a=a)),  # what the step assembles: advection_skew's
        (forms.advection, (ch.velocity,), dict(kw, a=a)),
        (forms.pressure_divergence, (ch.velocity, ch.pressure), kw),
    ]
    x = np.random.default_rng(0).standard_normal(ch.velocity.N)
    for form, bases, w in cases:
        shape = (bases[-1].N, bases[0].N)
        B = asm(forms.advection_skew if isinstance(form, SkewPart) else form, *bases, **w)
        for chunk in (5, 1024):  # chunks that split the 24 elements unevenly, and one chunk of all
            batched = BatchedForm(*bases, chunk=chunk)
            A = sp.coo_matrix((batched.data([(1.0, form, w)]), (batched.rows, batched.cols)), shape=shape).tocsr()
            assert abs(A - B).max() <= 1e-13 * abs(B).max(), form
            Ax = batched.apply([(1.0, form, w)], x)
            assert np.allclose(Ax, B @ x, rtol=0, atol=1e-13 * abs(B).max() * np.abs(x).sum())
    # the jets of a function at the points are scikit-fem's interpolation, on all elements or a chunk of them
    batched = BatchedForm(ch.velocity, chunk=5)
    ref = ch.velocity.interpolate(x)
    for cut in (slice(None), slice(5, 10)):
        field = batched.field(x, cut)
        assert np.allclose(field, np.asarray(ref)[:, cut], rtol=0, atol=1e-14 * np.abs(x).max())
        assert np.allclose(field.grad, np.asarray(ref.grad)[:, :, cut], rtol=0, atol=1e-13 * np.abs(x).max())
    # a sum of terms is the sum of their matrices, in one contraction (and its product with a vector)
    batched = BatchedForm(ch.velocity, chunk=7)
    terms = [(c, form, w) for c, (form, bases, w) in zip((2.0, -0.5, 3.0, 1.5, -1.0), cases[:5])]
    A = sp.coo_matrix((batched.data(terms), (batched.rows, batched.cols))).tocsr()
    B = sum(c * asm(forms.advection_skew if isinstance(form, SkewPart) else form, ch.velocity, **w)
            for c, form, w in terms)
    assert abs(A - B).max() <= 1e-13 * abs(B).max()
    assert np.allclose(batched.apply(terms, x), B @ x, rtol=0, atol=1e-13 * abs(B).max() * np.abs(x).sum())
    # the skew part of a form needs one space for both arguments
    with pytest.raises(ValueError, match="one space"):
        BatchedForm(ch.velocity, ch.pressure).data([(1.0, SkewPart(forms.pressure_divergence), kw)])


def test_batched_assembly_refuses_a_mesh_that_is_not_affine():
    mesh = skfem.MeshQuad().refined(1)
    p = mesh.p.copy()
    p[:, np.argmin(np.hypot(*(p - 0.5)))] += (0.2, 0.1)  # the middle node moved: four quadrilaterals, none a parallelogram
    mesh = skfem.MeshQuad(p, mesh.t)
    with pytest.raises(ValueError, match="affine"):
        BatchedForm(skfem.Basis(mesh, skfem.ElementQuad1()))


def test_advection_is_skew_and_the_rest_symmetric():
    ch, f = deformed(2)
    a = np.stack([np.sin(3 * ch.rhat), f.wr])
    N = asm(forms.advection_skew, ch.velocity, a=a, **f.forms_kwargs())
    assert abs(N + N.T).max() < 1e-14 * abs(N).max()
    for form in (forms.mass_J, forms.viscous):
        A = asm(form, ch.velocity, **f.forms_kwargs())
        assert abs(A - A.T).max() < 1e-14 * abs(A).max()


def test_ale_fields_match_the_map():
    """J, g_z, g_r of theory §2 for η = c z (η_z = c), at the quadrature points."""
    ch = Channel.build(Planar(), 2.0, 0.5, nz=2, nr=2, order=2)
    c = 0.05
    f = ALEFields.at(ch, c * ch.line.z, np.ones(ch.line.ndofs))
    zq = np.asarray(ch.velocity.global_coordinates())[0]
    R, rh = 0.5, ch.rhat
    assert np.allclose(f.J, (R + c * zq) / R, atol=1e-15)
    assert np.allclose(f.gz, -rh * c / (R + c * zq), atol=1e-15)
    assert np.allclose(f.gr, R / (R + c * zq), atol=1e-15)
    assert np.allclose(f.dJdt, 1.0 / R) and np.allclose(f.wr, rh / R)
    assert f.J_in == 1.0 and f.J_out == pytest.approx(1.0 + 2.0 * c / R)


def test_gradient_of_a_physical_field():
    """∇^η of the physical field u = (r, z) is [[0, 1], [1, 0]] on a deformed channel.

    With η = c z the field is P2 on Ω̂ (u_z = r = (1 + c ẑ/R) r̂), so the
    test sees only the map, not an interpolation error.
    """
    ch = Channel.build(Planar(), 2.0, 0.5, nz=3, nr=3, order=2, grading=1.3)
    c, R = 0.08, 0.5
    f = ALEFields.at(ch, c * ch.line.z, 0 * ch.line.z)
    u = ch.interpolate(lambda z, rh: ((1 + c * z / R) * rh, z))
    G = forms.grad_eta(ch.velocity.interpolate(u), f)
    for i, j, value in ((0, 0, 0.0), (0, 1, 1.0), (1, 0, 1.0), (1, 1, 0.0)):
        assert np.allclose(G[i][j], value, rtol=0, atol=1e-13)
    # u is divergence-free: so is its discrete ∫ J π ∇^η·u, for every π
    div = asm(forms.pressure_divergence, ch.velocity, ch.pressure, **f.forms_kwargs()) @ u
    assert np.abs(div).max() < 1e-13
