"""gather_rows: forward is plain indexing, backward equals autograd of indexing."""
import torch

from nicer_stream.model.gather import gather_rows


def _case():
    g = torch.Generator().manual_seed(0)
    table = torch.randn(7, 3, generator=g, dtype=torch.float64)
    idx = torch.tensor([[0, 3, 3], [6, 0, 3]])  # repeated rows must accumulate
    up = torch.randn(2, 3, 3, generator=g, dtype=torch.float64)
    return table, idx, up


def test_forward_equals_indexing():
    table, idx, _ = _case()
    t = table.clone().requires_grad_(True)
    out = gather_rows(t, idx)
    assert out.shape == (2, 3, 3)
    assert torch.equal(out.detach(), table[idx])
    assert out.requires_grad
    # Without gradient tracking it is the plain path and still equal.
    assert torch.equal(gather_rows(table, idx), table[idx])


def test_backward_equals_autograd_of_indexing_with_repeats():
    table, idx, up = _case()
    a = table.clone().requires_grad_(True)
    (gather_rows(a, idx) * up).sum().backward()
    b = table.clone().requires_grad_(True)
    (b[idx] * up).sum().backward()
    assert torch.allclose(a.grad, b.grad, atol=1e-12)
    # Row 3 is gathered three times: its gradient is the sum of three upstream rows.
    assert torch.allclose(a.grad[3], up[0, 1] + up[0, 2] + up[1, 2])
    # Unused rows get zero gradient.
    assert torch.all(a.grad[[1, 2, 4, 5]] == 0)


def test_gradcheck():
    table, idx, _ = _case()
    t = table.clone().requires_grad_(True)
    assert torch.autograd.gradcheck(lambda x: gather_rows(x, idx), (t,))


def test_preallocated_grad_accumulates_in_place_like_autograd():
    """With a `.grad` buffer the backward adds into it (no new tensor): two gathers of
    the same table and a prior content accumulate exactly as autograd's indexing does."""
    table, idx, up = _case()
    a = table.clone().requires_grad_(True)
    prior = torch.randn(7, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(5))
    a.grad = prior.clone()
    buf = a.grad
    ((gather_rows(a, idx) * up).sum() + gather_rows(a, idx[:1]).square().sum()).backward()
    b = table.clone().requires_grad_(True)
    ((b[idx] * up).sum() + b[idx[:1]].square().sum()).backward()
    assert a.grad is buf
    assert torch.allclose(a.grad, prior + b.grad, atol=1e-12)
