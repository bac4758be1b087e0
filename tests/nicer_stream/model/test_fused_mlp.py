"""The fused TangentMLP node against autograd over the reference ops."""
import torch

from nicer_stream.model.fused_mlp import FusedTangentMLP, softplus_beta
from nicer_stream.model.mlp import TangentMLP


def _inputs(n=7, d=5, dtype=torch.float64, seed=1):
    g = torch.Generator().manual_seed(seed)
    # Pre-activations O(0.01-0.1): both the kinked and the linear regime of softplus(100 z).
    h = (torch.randn(n, d, dtype=dtype, generator=g) * 0.05).requires_grad_()
    t = torch.randn(n, 3, d, dtype=dtype, generator=g).requires_grad_()
    return h, t


def test_softplus_matches_torch_including_large_inputs():
    z = torch.linspace(-5, 5, 2001, dtype=torch.float64)
    assert torch.allclose(softplus_beta(z), torch.nn.functional.softplus(z, beta=100.0, threshold=1e9), atol=1e-12)
    assert torch.isfinite(softplus_beta(torch.tensor([1e4, -1e4]))).all()


def test_values_and_gradients_equal_the_reference():
    torch.manual_seed(0)
    mlp = TangentMLP(5, 16, 3, 4, last_std=0.5).double()
    h, t = _inputs()
    g_out, g_tan = torch.randn(7, 4, dtype=torch.float64), torch.randn(7, 3, 4, dtype=torch.float64)
    res = []
    for fn in (mlp.forward, mlp.reference_forward):
        mlp.zero_grad()
        h.grad = t.grad = None
        out, tan = fn(h, t)
        ((out * g_out).sum() + (tan * g_tan).sum()).backward()
        res.append([out.detach(), tan.detach(), h.grad, t.grad] + [p.grad.clone() for p in mlp.parameters()])
    for a, b in zip(*res):
        assert torch.allclose(a, b, atol=1e-10, rtol=1e-8)


def test_gradcheck_float64():
    torch.manual_seed(0)
    mlp = TangentMLP(4, 6, 2, 3, last_std=0.5).double()
    h, t = _inputs(n=4, d=4)
    params = [p for layer in mlp.layers for p in (layer.weight, layer.bias)]
    assert torch.autograd.gradcheck(lambda h, t, *p: FusedTangentMLP.apply(h, t, 3, *p), (h, t, *params))


def test_only_some_outputs_used_and_frozen_weights():
    torch.manual_seed(0)
    mlp = TangentMLP(5, 8, 1, 2, last_std=0.5).double().requires_grad_(False)
    h, t = _inputs()
    out, tan = mlp(h, t)
    tan.sum().backward()  # the value output gets no gradient at all
    ref_h, ref_t = h.grad.clone(), t.grad.clone()
    h.grad = t.grad = None
    mlp.reference_forward(h, t)[1].sum().backward()
    assert torch.allclose(ref_h, h.grad) and torch.allclose(ref_t, t.grad)
    assert all(p.grad is None for p in mlp.parameters())


def test_softplus_in_place_branch_equals_autograd_branch():
    z = torch.linspace(-1, 1, 301, dtype=torch.float64)
    ref = softplus_beta(z.clone().requires_grad_()).detach()
    assert torch.equal(softplus_beta(z.clone()), ref)
