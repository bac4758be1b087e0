"""softplus_beta against torch's softplus, in both of its branches."""
import torch

from nicer_stream.model.softplus import softplus_beta


def test_softplus_matches_torch_including_large_inputs():
    z = torch.linspace(-5, 5, 2001, dtype=torch.float64)
    assert torch.allclose(softplus_beta(z), torch.nn.functional.softplus(z, beta=100.0, threshold=1e9), atol=1e-12)
    assert torch.isfinite(softplus_beta(torch.tensor([1e4, -1e4]))).all()


def test_softplus_in_place_branch_equals_autograd_branch():
    z = torch.linspace(-1, 1, 301, dtype=torch.float64)
    ref = softplus_beta(z.clone().requires_grad_()).detach()
    assert torch.equal(softplus_beta(z.clone()), ref)
