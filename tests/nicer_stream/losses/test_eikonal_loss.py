import torch

from nicer_stream.losses.eikonal import eikonal_loss


def sdf_gradient(sdf_fn, x: torch.Tensor) -> torch.Tensor:
    """(N, 3) gradient of `sdf_fn` ((N, 3) points -> (N,) SDF) at points `x` (N, 3), differentiable
    (create_graph), so an eikonal loss on it trains the SDF's parameters."""
    x = x.detach().requires_grad_(True)
    (grad,) = torch.autograd.grad(sdf_fn(x).sum(), x, create_graph=True)
    return grad


def _points(n=200):
    return torch.randn(n, 3, generator=torch.Generator().manual_seed(2), dtype=torch.float64)


def test_zero_for_exact_sphere_sdf():
    grad = sdf_gradient(lambda x: x.norm(dim=-1) - 0.5, _points())
    assert eikonal_loss(grad).item() < 1e-12


def test_positive_for_scaled_sdf_with_known_value():
    # Gradient norm of 2*(|x| - r) is 2 everywhere -> (2 - 1)^2 = 1.
    grad = sdf_gradient(lambda x: 2 * (x.norm(dim=-1) - 0.5), _points())
    assert abs(eikonal_loss(grad).item() - 1.0) < 1e-9


def test_gradient_flows_to_sdf_parameters():
    scale = torch.tensor(1.5, dtype=torch.float64, requires_grad=True)
    grad = sdf_gradient(lambda x: scale * (x.norm(dim=-1) - 0.5), _points())
    eikonal_loss(grad).backward()
    # d/ds (s - 1)^2 = 2 (s - 1) = 1 at s = 1.5
    assert abs(scale.grad.item() - 1.0) < 1e-9
