"""DenseGrids: trilinear interpolation, analytic Jacobian, Eq. 2 resolutions."""
import math

import torch

from nicer_stream.model.dense_grid import DenseGrids, geometric_resolutions


def _vertex(res: int, ijk) -> torch.Tensor:
    """Normalised coordinate of vertex ijk of a grid with `res` vertices per axis."""
    return torch.tensor(ijk, dtype=torch.float64) / (res - 1) * 2 - 1


def _row(grid: DenseGrids, level: int, ijk) -> torch.Tensor:
    r = grid.resolutions[level]
    off = sum(q**3 for q in grid.resolutions[:level])
    i, j, k = ijk
    return grid.table[off + (i * r + j) * r + k]


def _grid(res, dim=2, seed=0) -> DenseGrids:
    torch.manual_seed(seed)
    g = DenseGrids(res, dim).double()
    with torch.no_grad():
        g.table.normal_()
    return g


def test_exact_at_vertices():
    g = _grid([5, 3])
    verts = [(0, 0, 0), (4, 4, 4), (1, 2, 3), (4, 0, 2)]
    x = torch.stack([_vertex(5, v) for v in verts])
    out, _ = g(x)
    for n, v in enumerate(verts):
        assert torch.allclose(out[n, :2], _row(g, 0, v), atol=1e-12)
    # (4,0,2) on the 5-grid is (2,0,1) on the 3-grid.
    assert torch.allclose(out[3, 2:], _row(g, 1, (2, 0, 1)), atol=1e-12)


def test_linear_along_an_edge():
    g = _grid([4])
    a, b = _row(g, 0, (1, 2, 0)), _row(g, 0, (2, 2, 0))
    x0, x1 = _vertex(4, (1, 2, 0)), _vertex(4, (2, 2, 0))
    for t in (0.0, 0.2, 0.5, 0.9, 1.0):
        out, _ = g(((1 - t) * x0 + t * x1)[None])
        assert torch.allclose(out[0], (1 - t) * a + t * b, atol=1e-12)


def test_linear_field_reproduced_everywhere():
    res = [6, 9]
    g = DenseGrids(res, 1).double()
    A, B = torch.tensor([0.3, -1.2, 2.0], dtype=torch.float64), 0.7
    rows = []
    for r in res:
        ii = torch.arange(r, dtype=torch.float64) / (r - 1) * 2 - 1
        X = torch.stack(torch.meshgrid(ii, ii, ii, indexing="ij"), -1).reshape(-1, 3)
        rows.append(X @ A + B)
    with torch.no_grad():
        g.table.copy_(torch.cat(rows)[:, None])
    x = torch.rand(200, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(2)) * 2 - 1
    x[0] = torch.tensor([1.0, 1.0, 1.0])  # the upper corner (last cell, frac = 1)
    x[1] = torch.tensor([-1.0, -1.0, -1.0])
    out, jac = g(x, with_tangent=True)
    expect = x @ A + B
    assert torch.allclose(out[:, 0], expect, atol=1e-12)
    assert torch.allclose(out[:, 1], expect, atol=1e-12)
    # The Jacobian of a linear field is its gradient A at every point.
    assert torch.allclose(jac, A[None, :, None].expand(200, 3, 2), atol=1e-10)


def test_analytic_jacobian_equals_autograd():
    g = _grid([5, 7, 11], dim=3, seed=3)
    x = torch.rand(16, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(4)) * 1.9 - 0.95
    out, jac = g(x, with_tangent=True)
    assert out.shape == (16, 9) and jac.shape == (16, 3, 9)
    assert torch.equal(out, g(x)[0])
    for n in range(16):
        J = torch.autograd.functional.jacobian(lambda v: g(v[None])[0][0], x[n])  # (9, 3)
        assert torch.allclose(jac[n], J.T, atol=1e-9)


def test_gradients_reach_table():
    g = _grid([4, 5])
    x = torch.rand(10, 3, dtype=torch.float64) * 2 - 1
    out, jac = g(x, with_tangent=True)
    (out.sum() + jac.square().sum()).backward()
    assert g.table.grad is not None and g.table.grad.abs().sum() > 0
    assert torch.isfinite(g.table.grad).all()


def test_geometric_resolutions_eq2():
    fine = geometric_resolutions(32, 128, 8)
    b = math.exp((math.log(128) - math.log(32)) / 7)
    assert fine == [math.floor(32 * b**l + 1e-9) for l in range(8)]
    assert len(fine) == 8 and fine[0] == 32 and fine[-1] == 128
    assert all(a < c for a, c in zip(fine, fine[1:]))
    color = geometric_resolutions(16, 2048, 16)
    assert len(color) == 16 and color[0] == 16 and color[-1] == 2048
    assert all(a < c for a, c in zip(color, color[1:]))
    # Constant ratio b: each level within rounding of the geometric sequence.
    bc = math.exp((math.log(2048) - math.log(16)) / 15)
    assert all(abs(r - 16 * bc**l) < 1.0 for l, r in enumerate(color))
    assert geometric_resolutions(32, 128, 1) == [32]


def test_inference_cache_follows_fused_adam_steps():
    """fused Adam does not bump `_version`: `invalidate()` must refresh the grid_sample cache."""
    torch.manual_seed(0)
    g = DenseGrids([8, 12], 3, init_std=0.1)
    x = torch.rand(50, 3) * 2 - 1
    with torch.no_grad():
        g(x)  # fill the cache
    opt = torch.optim.Adam(g.parameters(), lr=0.5, fused=True)
    g.table.grad = torch.randn_like(g.table)
    opt.step()
    g.invalidate()
    with torch.no_grad():
        fast, _ = g(x)
    slow, _ = g(x)  # autograd path: always reads the table
    assert torch.allclose(fast, slow, atol=1e-5)


def test_inference_path_matches_training_path():
    """The grid_sample path (channels-last views, points split into per-thread batches,
    padded when N is not a multiple) gives the gather path's values and Jacobian."""
    torch.manual_seed(1)
    g = DenseGrids([7, 16, 33], 4, init_std=1.0)
    threads = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        for n in (5, 2049, 4097):
            x = torch.rand(n, 3, generator=torch.Generator().manual_seed(n)) * 2 - 1
            ref, ref_j = g(x, with_tangent=True)
            with torch.no_grad():
                out, jac = g(x, with_tangent=True)
            assert torch.allclose(out, ref, atol=1e-5) and torch.allclose(jac, ref_j, rtol=1e-4, atol=1e-3)
    finally:
        torch.set_num_threads(threads)
