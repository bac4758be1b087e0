"""The reverse-mode SDF-gradient node (its u contracted with a tangent, J u) against autograd over
the reference (forward-mode) ops."""
import pytest
import torch

from tests.nicer_stream.model.mlp_reference import reference_forward
from nicer_stream.model.mlp import GeometryMLP
from nicer_stream.model.sdf_grad_mlp import FusedSdfGradMLP


def _inputs(n=7, d=5, dtype=torch.float64, seed=1):
    g = torch.Generator().manual_seed(seed)
    # Pre-activations O(0.01-0.1): both the kinked and the linear regime of softplus(100 z).
    h = (torch.randn(n, d, dtype=dtype, generator=g) * 0.05).requires_grad_()
    t = torch.randn(n, 3, d, dtype=dtype, generator=g).requires_grad_()
    return h, t


def _fused(mlp):
    """(h, J) -> (out, J u): the fused node's u contracted with the input Jacobian."""
    def fn(h, t):
        out, u = mlp.value_and_input_grad(h)
        return out, torch.bmm(t, u.unsqueeze(-1)).squeeze(-1)
    return fn


def _run(fn, mlp, h, t, g_out, g_grad):
    mlp.zero_grad()
    h.grad = t.grad = None
    out, grad = fn(h, t)
    loss = 0
    if g_out is not None:
        loss = loss + (out * g_out).sum()
    if g_grad is not None:
        loss = loss + (grad * g_grad).sum()
    loss.backward()
    params = [p.grad.clone() if p.grad is not None else torch.zeros_like(p) for p in mlp.parameters()]
    return [out.detach(), grad.detach(), h.grad, t.grad] + params


@pytest.mark.parametrize("n_hidden", [1, 3])
@pytest.mark.parametrize("used", ["both", "value", "grad"])
def test_values_and_gradients_equal_the_forward_mode_reference(n_hidden, used):
    torch.manual_seed(0)
    mlp = GeometryMLP(5, 16, n_hidden, 4, last_std=0.5).double()
    h, t = _inputs()
    g_out = torch.randn(7, 4, dtype=torch.float64) if used != "grad" else None
    g_grad = torch.randn(7, 3, dtype=torch.float64) if used != "value" else None

    def reference(h, t):
        out, tan = reference_forward(mlp, h, t)
        return out, tan[:, :, 0]

    fused = _run(_fused(mlp), mlp, h, t, g_out, g_grad)
    ref = _run(reference, mlp, h, t, g_out, g_grad)
    for a, b in zip(fused, ref):
        if a is None and b is None:
            continue
        a = torch.zeros_like(b) if a is None else a
        b = torch.zeros_like(a) if b is None else b
        assert torch.allclose(a, b, atol=1e-10, rtol=1e-8)


def test_gradcheck_float64():
    torch.manual_seed(0)
    mlp = GeometryMLP(4, 6, 2, 3, last_std=0.5).double()
    h, _ = _inputs(n=4, d=4)
    params = [p for layer in mlp.layers for p in (layer.weight, layer.bias)]
    assert torch.autograd.gradcheck(lambda h, *p: FusedSdfGradMLP.apply(h, 3, *p), (h, *params))


def test_frozen_weights_get_no_gradient_and_inputs_still_do():
    torch.manual_seed(0)
    mlp = GeometryMLP(5, 8, 2, 2, last_std=0.5).double().requires_grad_(False)
    h, t = _inputs()
    out, grad = _fused(mlp)(h, t)
    (out.sum() + grad.square().sum()).backward()
    got = h.grad.clone(), t.grad.clone()
    h.grad = t.grad = None
    o, tan = reference_forward(mlp, h, t)
    (o.sum() + tan[:, :, 0].square().sum()).backward()
    assert torch.allclose(got[0], h.grad) and torch.allclose(got[1], t.grad)
    assert all(p.grad is None for p in mlp.parameters())
