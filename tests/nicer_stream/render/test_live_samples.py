"""Live samples: the probes' SDF interpolated to the gradient samples, and the transmittance mask."""
import torch

from nicer_stream.render.density import laplace_density
from nicer_stream.render.live_samples import interpolate_along_rays, kept_indices, live_mask
from nicer_stream.render.probe import composite_deltas
from nicer_stream.render.volume import render_weights, transmittance


def test_interpolation_is_exact_on_lines_and_constant_outside_the_knots():
    g = torch.Generator().manual_seed(0)
    t_knots = torch.sort(torch.rand(5, 8, generator=g), -1)[0]
    a, b = torch.randn(5, 1, generator=g), torch.randn(5, 1, generator=g)
    t = t_knots[:, :1] + (t_knots[:, -1:] - t_knots[:, :1]) * torch.rand(5, 30, generator=g)
    torch.testing.assert_close(interpolate_along_rays(t_knots, a * t_knots + b, t), a * t + b)
    before, after = t_knots[:, :1] - 0.5, t_knots[:, -1:] + 0.5
    v = a * t_knots + b
    torch.testing.assert_close(interpolate_along_rays(t_knots, v, before), v[:, :1])
    torch.testing.assert_close(interpolate_along_rays(t_knots, v, after), v[:, -1:])


def test_transmittance_is_what_the_weights_are_made_of():
    g = torch.Generator().manual_seed(1)
    sigma, deltas = torch.rand(4, 10, generator=g) * 5, torch.rand(4, 10, generator=g) * 0.3
    T = transmittance(sigma, deltas)
    assert torch.equal(T[:, 0], torch.ones(4))
    torch.testing.assert_close(T * (1 - torch.exp(-sigma * deltas)), render_weights(sigma, deltas))


def test_a_wall_across_the_rays_marks_exactly_the_samples_behind_it():
    """A plane at distance 1 along every ray: its SDF is linear in t, so the interpolated SDF is
    the true one and the mask is the exact transmittance's; the weights it drops sum to less
    than the threshold per ray, and the first sample is always kept."""
    g = torch.Generator().manual_seed(2)
    r, beta = 64, 0.01
    t_probe = torch.linspace(0.05, 3.0, 32).expand(r, 32)
    t = torch.sort(0.05 + 2.95 * torch.rand(r, 16, generator=g), -1)[0]
    far = torch.full((r,), 3.0)
    wall = 0.8 + 0.4 * torch.rand(r, 1, generator=g)
    sdf_true = wall - t
    sdf_est = interpolate_along_rays(t_probe, wall - t_probe, t)
    torch.testing.assert_close(sdf_est, sdf_true)
    for thr in (1e-2, 1e-4):
        live = live_mask(sdf_est, beta, t, far, thr)
        w = render_weights(laplace_density(sdf_true, beta), composite_deltas(t, far))
        T = transmittance(laplace_density(sdf_true, beta), composite_deltas(t, far))
        assert torch.equal(live, T >= thr)
        assert live[:, 0].all() and (~live).any()
        assert ((w * ~live).sum(-1) < thr).all()
        assert (t[~live] > wall.expand_as(t)[~live]).all()  # only samples behind the wall


def test_kept_indices_keep_every_live_sample_in_whole_buckets():
    g = torch.Generator().manual_seed(3)
    live = torch.rand(1000, generator=g) < 0.7
    idx = kept_indices(live, bucket=64)
    assert len(idx) % 64 == 0 and len(idx) - 64 < int(live.sum()) <= len(idx)
    assert live[idx].sum() == live.sum() and len(set(idx.tolist())) == len(idx)  # all live, none twice
    assert kept_indices(torch.ones(100, dtype=torch.bool), 64) is None  # rounding up reaches N: all of them
    assert kept_indices(live, bucket=1).tolist() == live.nonzero()[:, 0].tolist()


def test_a_band_behind_the_wall_stays_live():
    """`keep_band`: samples less than the band behind the wall stay live however dark."""
    t = torch.linspace(0.1, 3.0, 64).expand(8, 64)
    sdf = 1.0 - t  # a wall at 1
    far = torch.full((8,), 3.0)
    plain = live_mask(sdf, 0.01, t, far, 1e-4)
    banded = live_mask(sdf, 0.01, t, far, 1e-4, keep_band=0.5)
    assert torch.equal(banded, plain | (t < 1.5)) and (banded & ~plain).any()
    assert not banded[t > 1.5].any()
