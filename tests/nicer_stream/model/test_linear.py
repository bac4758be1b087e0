"""The oneDNN dense layer (`model/linear.py`) against torch's addmm/mm: values, gradients, the
module's parameters, and the paths that must not take it."""
import pytest
import torch
import torch.nn.functional as F

from nicer_stream.model.linear import Linear, LinearFunction, linear, linear_reference, matmul, onednn_available

needs_onednn = pytest.mark.skipif(not onednn_available(torch.zeros(1)), reason="no oneDNN in this torch build")


def _close(a: torch.Tensor, b: torch.Tensor, rtol: float = 2e-6) -> bool:
    """Agreement to float32 rounding, relative to the output's scale."""
    a, b = a.detach(), b.detach()
    return float((a - b).abs().max()) <= rtol * float(b.abs().max())


@needs_onednn
@pytest.mark.parametrize("n,i,o", [(1, 71, 64), (37, 121, 3), (16384, 64, 33), (5000, 71, 64)])
def test_linear_and_matmul_equal_the_reference(n, i, o):
    g = torch.Generator().manual_seed(n)
    x, w, b = torch.randn(n, i, generator=g), torch.randn(o, i, generator=g), torch.randn(o, generator=g)
    assert _close(linear(x, w, b), linear_reference(x, w, b))
    assert _close(linear(x, w), x @ w.t())
    y = torch.randn(n, o, generator=g)
    assert _close(matmul(y, w), y @ w)
    # A column slice (non-contiguous rows) gives the same product.
    wide = torch.randn(n, i + 5, generator=g)
    assert _close(linear(wide[:, 2:2 + i], w, b), linear_reference(wide[:, 2:2 + i], w, b))


@needs_onednn
def test_linear_function_gradients_equal_autograd():
    g = torch.Generator().manual_seed(1)
    x = torch.randn(3000, 71, generator=g)
    w, b = torch.randn(64, 71, generator=g) * 0.1, torch.randn(64, generator=g)
    up = torch.randn(3000, 64, generator=g)
    grads = []
    for fn in (LinearFunction.apply, F.linear):
        xs, ws, bs = (t.clone().requires_grad_() for t in (x, w, b))
        (fn(xs, ws, bs) * up).sum().backward()
        grads.append((xs.grad, ws.grad, bs.grad))
    for fast, ref in zip(*grads):
        assert _close(fast, ref, 1e-5)


def test_linear_module_keeps_nn_linear_parameters_and_reference_dtype_paths():
    layer = Linear(5, 3)
    assert set(layer.state_dict()) == {"weight", "bias"}
    x = torch.randn(11, 5, dtype=torch.float64)
    assert not onednn_available(x)  # float64 (gradcheck) takes torch's ops
    layer64 = Linear(5, 3).double()
    assert torch.autograd.gradcheck(layer64, (x.clone().requires_grad_(),))
    x32 = torch.randn(11, 5)
    assert _close(layer(x32), F.linear(x32, layer.weight, layer.bias))
    layer(x32).sum().backward()  # a graph through the module reaches its parameters
    assert layer.weight.grad is not None and layer.bias.grad is not None


def test_disabled_by_environment(monkeypatch):
    monkeypatch.setenv("NICER_STREAM_ONEDNN", "0")
    assert not onednn_available(torch.zeros(1))
