"""HashGrids: dense levels interpolate like DenseGrids, hashed levels are deterministic."""
import torch

from nicer_stream.model.dense_grid import DenseGrids
from nicer_stream.model.hash_grid import HashGrids


def _hash(levels=4, r_min=4, r_max=32, log2=9, dim=2, seed=0) -> HashGrids:
    torch.manual_seed(seed)
    h = HashGrids(levels, dim, r_min, r_max, log2).double()
    with torch.no_grad():
        h.table.normal_()
    return h


def _x(n, seed=1):
    return torch.rand(n, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(seed)) * 2 - 1


def test_output_shape_and_dense_split():
    h = _hash()
    assert h.resolutions[0] == 4 and h.resolutions[-1] == 32
    # 4^3 and 8^3 fit in 2^9 rows; 16^3 and 32^3 are hashed.
    assert h.dense.tolist() == [r**3 <= 512 for r in h.resolutions]
    assert h.dense.any() and not h.dense.all()
    out = h(_x(13))
    assert out.shape == (13, h.out_dim) == (13, 4 * 2)


def test_dense_levels_equal_dense_grid_interpolation():
    h = _hash()
    x = _x(50)
    out = h(x).reshape(50, 4, 2)
    for l, r in enumerate(h.resolutions):
        if not h.dense[l]:
            continue
        d = DenseGrids([r], 2).double()
        with torch.no_grad():
            d.table.copy_(h.table[l * h.size: l * h.size + r**3])
        assert torch.allclose(out[:, l], d(x)[0], atol=1e-12)


def test_hashed_level_exact_at_vertex():
    h = _hash()
    l = 3
    r = h.resolutions[l]
    assert not h.dense[l]
    ijk = torch.tensor([5, 17, 30])
    x = (ijk.double() / (r - 1) * 2 - 1)[None]
    row = (int(ijk[0]) * 1 ^ int(ijk[1]) * 2654435761 ^ int(ijk[2]) * 805459861) % h.size
    assert torch.allclose(h(x).reshape(4, 2)[l], h.table[l * h.size + row], atol=1e-12)


def test_deterministic():
    h = _hash()
    x = _x(20, seed=5)
    assert torch.equal(h(x), h(x.clone()))


def test_gradients_reach_table_all_levels():
    h = _hash()
    h(_x(64)).square().sum().backward()
    g = h.table.grad.reshape(4, h.size, 2)
    assert torch.isfinite(g).all()
    for l in range(4):
        assert g[l].abs().sum() > 0
