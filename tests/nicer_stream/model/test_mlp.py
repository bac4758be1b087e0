"""GeometryMLP: the reference (forward-mode) tangent and the fused SDF gradient equal the autograd Jacobian."""
import torch

from tests.nicer_stream.model.mlp_reference import reference_forward
from nicer_stream.model.mlp import GeometryMLP, plain_mlp


def test_tangent_equals_autograd_jacobian():
    torch.manual_seed(0)
    mlp = GeometryMLP(5, 16, 3, 4, last_std=0.5).double()
    # Softplus(beta=100) is near-linear/kinked: keep pre-activations O(0.01) so both regimes occur.
    g = torch.Generator().manual_seed(1)
    x = torch.randn(6, 3, dtype=torch.float64, generator=g) * 0.05
    A = torch.randn(3, 5, dtype=torch.float64, generator=g)

    def f(v):  # R^3 -> R^4, input of the MLP is a linear map of v
        return mlp(v @ A)

    out, tan = reference_forward(mlp, x @ A, A.expand(6, 3, 5))
    out_f, u = mlp.value_and_input_grad(x @ A)
    grad0 = torch.bmm(A.expand(6, 3, 5), u.unsqueeze(-1)).squeeze(-1)  # J u
    assert torch.allclose(out, f(x), atol=1e-12) and torch.allclose(out_f, f(x), atol=1e-12)
    assert tan.shape == (6, 3, 4) and grad0.shape == (6, 3)
    for n in range(6):
        J = torch.autograd.functional.jacobian(lambda v: f(v[None])[0], x[n])  # (4, 3)
        assert torch.allclose(tan[n], J.T, atol=1e-10)
        assert torch.allclose(grad0[n], J[0], atol=1e-10)


def test_no_tangent_and_init():
    torch.manual_seed(0)
    mlp = GeometryMLP(4, 8, 1, 2, last_std=1e-4)
    assert torch.all(mlp.layers[-1].bias == 0)
    assert mlp.layers[-1].weight.std() < 1e-3
    out = mlp(torch.randn(3, 4))
    assert out.shape == (3, 2)
    assert out.abs().max() < 1e-2


def test_plain_mlp_shape():
    m = plain_mlp(7, 16, 2, 3)
    assert m(torch.randn(5, 7)).shape == (5, 3)
    assert sum(isinstance(x, torch.nn.Linear) for x in m) == 3
