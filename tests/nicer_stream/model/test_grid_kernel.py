"""The compiled grid kernel against the pure-torch reference paths (values, Jacobians,
gradients w.r.t. the table and the points, gradcheck in float64)."""
import pytest
import torch

from nicer_stream.model.dense_grid import DenseGrids
from nicer_stream.model.grid_kernel import GridInterp, kernel_available
from nicer_stream.model.hash_grid import HashGrids

pytestmark = pytest.mark.skipif(not kernel_available(torch.zeros(1)), reason="grid kernel could not be built here")


def _x(n, seed=1, spread=1.1):
    # Some points outside [-1, 1]: the clamp must pass no gradient there, as in the reference.
    g = torch.Generator().manual_seed(seed)
    return ((torch.rand(n, 3, dtype=torch.float64, generator=g) * 2 - 1) * spread).requires_grad_()


def _dense():
    torch.manual_seed(0)
    d = DenseGrids([5, 9, 16], 3).double()
    with torch.no_grad():
        d.table.normal_()
    return d


def _hash():
    torch.manual_seed(0)
    h = HashGrids(4, 2, 4, 32, 9).double()
    with torch.no_grad():
        h.table.normal_()
    return h


def _grads(fn, x, table, weights):
    x.grad = None
    table.grad = None
    outs = [o for o in fn(x) if o is not None]
    sum((o * w).sum() for o, w in zip(outs, weights)).backward()
    return [o.detach() for o in outs] + [x.grad.clone(), table.grad.clone()]


@pytest.mark.parametrize("with_jac", [False, True])
def test_dense_kernel_equals_reference(with_jac):
    d, x = _dense(), _x(200)
    g = torch.Generator().manual_seed(2)
    w = [torch.randn(200, d.out_dim, dtype=torch.float64, generator=g),
         torch.randn(200, 3, d.out_dim, dtype=torch.float64, generator=g)]
    fast = _grads(lambda p: d(p, with_jac), x, d.table, w)
    ref = _grads(lambda p: d.reference_forward(p, with_jac), x, d.table, w)
    for a, b in zip(fast, ref):
        assert torch.allclose(a, b, atol=1e-10)


@pytest.mark.parametrize("channels", [1, 2, 4, 32])
@pytest.mark.parametrize("n", [1, 7, 37])
def test_every_channel_count_equals_reference(channels, n):
    # The kernel has compile-time paths for 2, 4 and 32 channels and a run-time one for others:
    # every path must give the reference's values and gradients, for one point and for several.
    torch.manual_seed(channels)
    d = DenseGrids([4, 7], channels).double()
    with torch.no_grad():
        d.table.normal_()
    x = _x(n, seed=n)
    g = torch.Generator().manual_seed(n)
    w = [torch.randn(n, d.out_dim, dtype=torch.float64, generator=g),
         torch.randn(n, 3, d.out_dim, dtype=torch.float64, generator=g)]
    fast = _grads(lambda p: d(p, True), x, d.table, w)
    ref = _grads(lambda p: d.reference_forward(p, True), x, d.table, w)
    for a, b in zip(fast, ref):
        assert torch.allclose(a, b, atol=1e-10)


def test_hash_kernel_equals_reference():
    h, x = _hash(), _x(300)
    w = [torch.randn(300, h.out_dim, dtype=torch.float64, generator=torch.Generator().manual_seed(3))]
    fast = _grads(lambda p: (h(p),), x, h.table, w)
    ref = _grads(lambda p: (h.reference_forward(p),), x, h.table, w)
    for a, b in zip(fast, ref):
        assert torch.allclose(a, b, atol=1e-10)


def test_gradcheck_table_and_points():
    d = DenseGrids([4, 6], 2).double()
    table = torch.randn_like(d.table).requires_grad_()
    x = (torch.rand(6, 3, dtype=torch.float64) * 1.8 - 0.9).requires_grad_()
    assert torch.autograd.gradcheck(lambda t, p: GridInterp.apply(t, p, d.spec, True), (table, x))


def test_persistent_grad_buffer_is_added_in_place():
    d, x = _dense(), _x(50)
    buf = torch.ones_like(d.table)
    d.table.grad = buf
    d(x)[0].sum().backward()
    assert d.table.grad is buf and not torch.equal(buf, torch.ones_like(buf))
