"""Positional encoding gamma(x) values and its analytic Jacobian."""
import math

import torch

from nicer_stream.model.positional import encoding_dim, positional_encoding


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
    assert torch.equal(enc, positional_encoding(x, L))
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
