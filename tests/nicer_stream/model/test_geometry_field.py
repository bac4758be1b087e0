"""GeometryField: sphere initialisation, analytic SDF gradient, fine level switch."""
import torch

from nicer_stream.config import ModelConfig
from nicer_stream.model.geometry import GeometryField

SMALL = ModelConfig(coarse_res=8, coarse_dim=4, coarse_hidden=16, fine_levels=2, fine_res_min=6,
                    fine_res_max=9, fine_hidden=16, fine_layers=2, geo_feature_dim=5)


def _points(n, seed=0, dtype=torch.float32):
    return (torch.rand(n, 3, generator=torch.Generator().manual_seed(seed)) * 1.8 - 0.9).to(dtype)


def test_default_init_is_sphere():
    torch.manual_seed(0)
    cfg = ModelConfig()  # the real (paper) sizes and initialisation
    geo = GeometryField(cfg)
    x = _points(512)
    with torch.no_grad():
        for fine in (False, True):
            s = geo(x, use_fine=fine)
            resid = s.sdf - (cfg.sphere_radius - x.norm(dim=-1))
            assert resid.abs().max() < 1e-2
            assert s.z_coarse.shape == s.z_fine.shape == (512, cfg.geo_feature_dim)
            assert s.grad is None
        s = geo(x, with_grad=True)
    # The normal of the initial sphere points to the centre (into free space).
    cos = torch.nn.functional.cosine_similarity(s.grad, -x, dim=-1)
    assert cos.min() > 0.99


def _perturbed(seed=1) -> GeometryField:
    """A double-precision field whose MLPs and grids are far from the initialisation."""
    torch.manual_seed(seed)
    geo = GeometryField(SMALL).double()
    with torch.no_grad():
        for p in geo.parameters():
            p.add_(torch.randn_like(p) * 0.3)
    return geo


def test_grad_equals_autograd():
    geo = _perturbed()
    x = _points(8, seed=2, dtype=torch.float64)
    for fine in (False, True):
        s = geo(x, use_fine=fine, with_grad=True)
        # Same values up to rounding: with tangents the value rows share a matmul with them, and
        # BLAS may block a taller matrix differently (bit-equal on some CPUs, not on all).
        assert torch.allclose(s.sdf, geo(x, use_fine=fine).sdf, rtol=1e-12, atol=1e-12)
        xr = x.clone().requires_grad_(True)
        (g,) = torch.autograd.grad(geo(xr, use_fine=fine).sdf.sum(), xr)
        assert torch.allclose(s.grad, g, atol=1e-9), (fine, (s.grad - g).abs().max())
        assert s.grad.abs().max() > 0.1


def test_grad_is_differentiable_wrt_parameters():
    geo = _perturbed()
    s = geo(_points(16, dtype=torch.float64), with_grad=True)
    ((s.grad.norm(dim=-1) - 1) ** 2).mean().backward()  # Eikonal-style, first-order only
    assert geo.coarse_grid.table.grad.abs().sum() > 0
    assert geo.fine_grid.table.grad.abs().sum() > 0


def test_grad_is_differentiable_wrt_points_and_parameters_against_second_order_autograd(monkeypatch):
    """The tracker's and BA's path: d(loss of the normals)/dx and /dparams through the
    part-by-part contraction, against autograd's double backward over the plain value (the
    pure-torch grids: the compiled kernel's backward is first-order only)."""
    geo = _perturbed()
    x0 = _points(6, seed=4, dtype=torch.float64)
    w = torch.randn(6, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(5))
    got, ref = [], []
    for analytic in (True, False):
        geo.zero_grad()
        x = x0.clone().requires_grad_(True)
        if analytic:
            g = geo(x, with_grad=True).grad
        else:
            monkeypatch.setenv("NICER_STREAM_KERNELS", "0")
            (g,) = torch.autograd.grad(geo(x).sdf.sum(), x, create_graph=True)
        (g * w).sum().backward()
        (got if analytic else ref).append(x.grad.clone())
        (got if analytic else ref).extend(torch.zeros_like(p) if p.grad is None else p.grad.clone() for p in geo.parameters())
    for a, b in zip(got, ref):
        assert torch.allclose(a, b, atol=1e-8), (a - b).abs().max()


def test_use_fine_false_ignores_fine_grid():
    geo = _perturbed()
    x = _points(32, seed=3, dtype=torch.float64)
    coarse0, full0 = geo(x, use_fine=False, with_grad=True), geo(x, use_fine=True)
    with torch.no_grad():
        geo.fine_grid.table.add_(torch.randn_like(geo.fine_grid.table))
        for p in geo.fine_mlp.parameters():
            p.add_(torch.randn_like(p) * 0.3)
    coarse1, full1 = geo(x, use_fine=False, with_grad=True), geo(x, use_fine=True)
    assert torch.equal(coarse0.sdf, coarse1.sdf)
    assert torch.equal(coarse0.grad, coarse1.grad)
    assert torch.equal(coarse1.z_fine, torch.zeros_like(coarse1.z_fine))
    assert (full0.sdf - full1.sdf).abs().max() > 1e-3  # the full SDF does see the fine level


def test_sphere_moved_to_the_camera():
    """The SLAM's start: the sphere centred on the first camera, which is then in free space
    even where the bound's centre is further from it than the default radius."""
    torch.manual_seed(0)
    geo = GeometryField(ModelConfig())
    camera = torch.tensor([0.6, -0.7, 0.5])  # |camera| = 1.05: inside the solid of the default sphere
    with torch.no_grad():
        assert geo(camera[None]).sdf[0] < 0
        geo.set_sphere(camera, 0.7)
        x = _points(256)
        s = geo(x)
        assert (s.sdf - (0.7 - (x - camera).norm(dim=-1))).abs().max() < 1e-2
        assert geo(camera[None]).sdf[0] > 0.65


def test_grad_equals_autograd_with_a_moved_sphere():
    geo = _perturbed()
    geo.set_sphere(torch.tensor([0.3, -0.2, 0.4], dtype=torch.float64), 0.6)
    x = _points(8, seed=3, dtype=torch.float64)
    s = geo(x, with_grad=True)
    xr = x.clone().requires_grad_(True)
    (g,) = torch.autograd.grad(geo(xr).sdf.sum(), xr)
    assert torch.allclose(s.grad, g, atol=1e-9), (s.grad - g).abs().max()


def test_sdf_alone_equals_the_forward_value():
    geo = _perturbed()
    x = _points(50, seed=6, dtype=torch.float64)
    for fine in (False, True):
        with torch.no_grad():
            assert torch.allclose(geo.sdf(x, use_fine=fine), geo(x, use_fine=fine).sdf, rtol=0, atol=1e-12)
    geo32 = _perturbed().float()
    with torch.no_grad():
        a, b = geo32.sdf(x.float()), geo32(x.float()).sdf
    assert torch.allclose(a, b, rtol=0, atol=1e-5 * float(b.abs().max()))
