"""Positional encoding gamma(x) values and its analytic Jacobian; the compiled encoding
(`kernels/encoding.cpp`) against the tensor-op reference."""
import math

import pytest
import torch

from nicer_stream.model.positional import (ENCODING_KERNEL, encoding_dim, positional_encoding,
                                           positional_encoding_reference)

needs_kernel = pytest.mark.skipif(not ENCODING_KERNEL.available(torch.zeros(1)), reason="encoding kernel could not be built here")


def test_values_match_definition():
    x = torch.tensor([[0.25, -0.5, 0.1], [0.0, 1.0, -0.3]], dtype=torch.float64)
    L = 3
    enc = positional_encoding(x, L)
    assert enc.shape == (2, encoding_dim(L, 3)) == (2, 3 + 2 * 3 * L)
    assert torch.equal(enc[:, :3], x)
    for k in range(L):
        f = 2.0**k * math.pi
        assert torch.allclose(enc[:, 3 + 3 * k: 6 + 3 * k], torch.sin(f * x), atol=1e-12)
        assert torch.allclose(enc[:, 3 + 3 * L + 3 * k: 6 + 3 * L + 3 * k], torch.cos(f * x), atol=1e-12)
    # A known value: sin(2 pi * 0.25) = 1.
    assert abs(enc[0, 3 + 3 * 1].item() - 1.0) < 1e-12


def test_zero_levels_is_identity():
    x = torch.randn(5, 3)
    assert torch.equal(positional_encoding(x, 0), x)


def test_tangent_equals_autograd_jacobian():
    g = torch.Generator().manual_seed(1)
    x = torch.rand(4, 3, generator=g, dtype=torch.float64) * 2 - 1
    L = 4
    enc, jac = positional_encoding(x, L, with_tangent=True)
    assert torch.allclose(enc, positional_encoding(x, L), atol=1e-12, rtol=0)
    assert jac.shape == (4, 3, encoding_dim(L))
    for n in range(4):
        J = torch.autograd.functional.jacobian(lambda v: positional_encoding(v[None], L)[0], x[n])  # (E, 3)
        assert torch.allclose(jac[n], J.T, atol=1e-10)


def test_encoding_grad_equals_the_jacobian_contraction_and_its_gradients():
    from nicer_stream.model.positional import encoding_grad

    g = torch.Generator().manual_seed(3)
    L = 4
    x = (torch.rand(9, 3, generator=g, dtype=torch.float64) * 2 - 1).requires_grad_()
    u = torch.randn(9, encoding_dim(L), generator=g, dtype=torch.float64).requires_grad_()
    enc, jac = positional_encoding(x, L, with_tangent=True)
    ref = torch.bmm(jac, u[:, :, None])[..., 0]
    assert torch.allclose(encoding_grad(enc, u, L), ref, atol=1e-12)
    # Second-order terms (x through enc) and the u path, both against autograd over J u.
    assert torch.autograd.gradcheck(lambda x, u: encoding_grad(positional_encoding(x, L), u, L), (x, u))


@needs_kernel
@pytest.mark.parametrize("dtype,tol", [(torch.float32, 2e-6), (torch.float64, 1e-12)])
@pytest.mark.parametrize("levels", [4, 6])
def test_kernel_matches_the_reference_values_and_gradient(dtype, tol, levels):
    g = torch.Generator().manual_seed(7)
    x = (torch.rand(1001, 3, generator=g, dtype=dtype) * 2 - 1).requires_grad_()
    w = torch.randn(1001, encoding_dim(levels), generator=g, dtype=dtype)
    enc = positional_encoding(x, levels)
    ref = positional_encoding_reference(x, levels)
    assert type(enc.grad_fn).__name__ == "_EncodingBackward"
    # sin(2^5 pi x) of a float32 x: the argument is ~100, so a few ulp of it are ~1e-5 absolute.
    assert torch.allclose(enc, ref, atol=tol * 2**levels, rtol=0)
    (gx,) = torch.autograd.grad(enc, x, w)
    (gr,) = torch.autograd.grad(ref, x, w)
    assert torch.allclose(gx, gr, atol=tol * 4**levels, rtol=tol)


@needs_kernel
def test_kernel_passes_gradcheck_in_float64():
    x = (torch.rand(6, 3, dtype=torch.float64) * 2 - 1).requires_grad_()
    assert torch.autograd.gradcheck(lambda v: positional_encoding(v, 3), (x,))


@needs_kernel
def test_a_points_encoding_does_not_depend_on_its_place_in_the_batch():
    """The vector sin/cos and the padded tail: the same bits wherever a point sits (probes in chunks)."""
    g = torch.Generator().manual_seed(2)
    x = torch.rand(37, 3, generator=g) * 2 - 1
    whole = positional_encoding(x, 6)
    for lo, hi in ((0, 5), (5, 6), (11, 37), (1, 30)):
        assert torch.equal(positional_encoding(x[lo:hi], 6), whole[lo:hi])


def test_reference_is_taken_where_the_kernel_does_not_apply(monkeypatch):
    x = torch.rand(4, 2)
    assert positional_encoding(x, 2).shape == (4, encoding_dim(2, 2))  # d = 2: the reference's
    monkeypatch.setenv("NICER_STREAM_KERNELS", "0")
    y = torch.rand(4, 3, requires_grad=True)
    assert torch.equal(positional_encoding(y, 3), positional_encoding_reference(y, 3))
    assert type(positional_encoding(y, 3).grad_fn).__name__ != "_EncodingBackward"
