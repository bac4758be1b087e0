"""softplus_beta against torch's softplus, in both of its branches, and the compiled pass
(`kernels/softplus.cpp`) against the reference."""
import pytest
import torch

from nicer_stream.model.softplus import (SOFTPLUS_BETA, SOFTPLUS_KERNEL, softplus_and_sigmoid, softplus_beta,
                                         softplus_beta_reference, sweep_adjoint, sweep_adjoint_reference)

needs_kernel = pytest.mark.skipif(not SOFTPLUS_KERNEL.available(torch.zeros(1)), reason="softplus kernel could not be built here")


def test_softplus_matches_torch_including_large_inputs():
    z = torch.linspace(-5, 5, 2001, dtype=torch.float64)
    assert torch.allclose(softplus_beta(z), torch.nn.functional.softplus(z, beta=100.0, threshold=1e9), atol=1e-12)
    assert torch.isfinite(softplus_beta(torch.tensor([1e4, -1e4]))).all()


def test_softplus_in_place_branch_equals_autograd_branch():
    z = torch.linspace(-1, 1, 301, dtype=torch.float64)
    ref = softplus_beta_reference(z.clone().requires_grad_()).detach()
    assert torch.equal(softplus_beta_reference(z.clone()), ref)


def test_softplus_keeps_its_graph_when_one_is_needed():
    z = torch.linspace(-0.05, 0.05, 101, dtype=torch.float64, requires_grad=True)
    softplus_beta(z).sum().backward()
    assert torch.allclose(z.grad, torch.sigmoid(SOFTPLUS_BETA * z.detach()), atol=1e-12)


@needs_kernel
@pytest.mark.parametrize("dtype,tol", [(torch.float32, 2e-7), (torch.float64, 1e-15)])
def test_kernel_matches_reference_values_and_sigmoid(dtype, tol):
    g = torch.Generator().manual_seed(0)
    # Pre-activations as the MLPs see them (|beta z| mostly below 10), a non-contiguous view,
    # and the tails where exp(-|a|) is capped.
    z = (torch.randn(3000, 70, generator=g, dtype=dtype) * 0.05)[:, ::2]
    z = torch.cat([z.reshape(-1), torch.tensor([-30.0, -0.8, 0.0, 0.8, 30.0], dtype=dtype)])
    sp, s = softplus_and_sigmoid(z)
    assert torch.allclose(sp, softplus_beta_reference(z), rtol=0, atol=tol * 10)
    assert torch.allclose(s, torch.sigmoid(SOFTPLUS_BETA * z), rtol=0, atol=tol * 10)
    assert torch.equal(softplus_beta(z), sp)  # no graph asked for: the same pass


@needs_kernel
def test_kernel_passes_nan_and_infinity_through():
    z = torch.tensor([float("nan"), float("inf"), -float("inf"), 1.0])
    sp, s = softplus_and_sigmoid(z)
    assert torch.isnan(sp[0]) and torch.isnan(s[0])  # a diverged map stays visible
    # 1 to a float32 ulp: with AVX-512, -ffast-math builds the division from a reciprocal estimate.
    assert sp[1] == float("inf") and 1.0 - 1.2e-7 <= s[1] <= 1.0
    assert sp[2] == 0.0 and s[2] < 1e-30
    assert torch.allclose(sp[3], torch.tensor(1.0))


@needs_kernel
def test_kernel_gives_each_value_independently_of_position_and_alignment():
    """Every element takes the same vector code (no scalar tail or alignment peel), so a value
    does not depend on where it sits: re-renders in a fresh process match the run's own."""
    z = torch.randn(1003, generator=torch.Generator().manual_seed(1)) * 0.05
    whole = softplus_and_sigmoid(z)
    for start in (1, 3, 17):
        part = softplus_and_sigmoid(z[start:].clone())
        assert torch.equal(part[0], whole[0][start:]) and torch.equal(part[1], whole[1][start:])


@needs_kernel
@pytest.mark.parametrize("dtype,tol", [(torch.float32, 1e-6), (torch.float64, 1e-13)])
def test_sweep_adjoint_kernel_matches_reference(dtype, tol):
    # 4099 values: whole 4096-chunks and a tail; sigmoid values in (0, 1), non-contiguous input.
    g = torch.Generator().manual_seed(0)
    vbar, u = (torch.randn(4099, 2, dtype=dtype, generator=g)[:, 0] for _ in range(2))
    s = torch.rand(4099, dtype=dtype, generator=g)
    got, ref = sweep_adjoint(vbar, u, s), sweep_adjoint_reference(vbar, u, s)
    for a, b in zip(got, ref):
        assert a.shape == b.shape and torch.allclose(a, b, rtol=tol, atol=tol)
