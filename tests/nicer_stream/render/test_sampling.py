"""ray_box, stratified and inverse-CDF sampling."""
import torch

from nicer_stream.render.sampling import ray_box, sample_pdf, stratified


def test_ray_box_known_rays():
    o = torch.tensor([
        [-3.0, 0.0, 0.0],   # outside, along +x through the centre
        [0.0, 0.0, 0.0],    # inside, along +z
        [0.5, 0.2, -0.1],   # inside, along -y
        [0.0, 0.0, -5.0],   # outside, diagonal in y-z: reaches z = -1 at y = 4, misses
        [0.0, 2.0, 0.0],    # outside, parallel to the cube: misses
    ])
    s = 2**-0.5
    d = torch.tensor([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0], [0, s, s], [1.0, 0, 0]])
    near, far = ray_box(o, d)
    assert torch.allclose(near[:3], torch.tensor([2.0, -1.0, -0.8]), atol=1e-6)
    assert torch.allclose(far[:3], torch.tensor([4.0, 1.0, 1.2]), atol=1e-6)
    assert near[3] > far[3]
    assert near[4] > far[4]


def test_ray_box_diagonal_hit():
    s = 2**-0.5
    o = torch.tensor([[0.0, -2.0, -2.0], [0.3, 0.0, 0.0]])
    d = torch.tensor([[0.0, s, s], [-1.0, 0.0, 0.0]])
    near, far = ray_box(o, d, lo=-1.0, hi=1.0)
    assert torch.allclose(near, torch.tensor([1 / s, -0.7]), atol=1e-6)
    assert torch.allclose(far, torch.tensor([3 / s, 1.3]), atol=1e-6)
    # Points at near/far lie on the cube surface.
    p = o + far[:, None] * d
    assert torch.allclose(p.abs().amax(-1), torch.ones(2), atol=1e-6)


def test_stratified_sorted_within_bounds():
    torch.manual_seed(0)
    near = torch.tensor([0.1, 1.0, -0.5])
    far = torch.tensor([2.0, 1.5, 0.5])
    for jitter in (True, False):
        t = stratified(near, far, 16, jitter)
        assert t.shape == (3, 16)
        assert (t >= near[:, None]).all() and (t <= far[:, None]).all()
        assert (t[:, 1:] >= t[:, :-1]).all()
        # One sample per equal bin.
        k = ((t - near[:, None]) / (far - near)[:, None] * 16).floor()
        assert torch.equal(k, torch.arange(16.0).expand(3, 16))
    t = stratified(near, far, 4, jitter=False)
    assert torch.allclose(t[0], 0.1 + 1.9 * torch.tensor([0.125, 0.375, 0.625, 0.875]))


def test_sample_pdf_concentrates_on_delta_bin():
    torch.manual_seed(0)
    bins = torch.linspace(0, 1, 11).expand(4, 11).contiguous()
    w = torch.zeros(4, 10)
    w[torch.arange(4), torch.tensor([0, 3, 7, 9])] = 1.0
    for jitter in (True, False):
        t = sample_pdf(bins, w, 64, jitter)
        assert t.shape == (4, 64)
        assert (t >= 0).all() and (t <= 1).all()
        b = (t * 10).floor().clamp(max=9)
        for r, k in enumerate([0, 3, 7, 9]):
            assert (b[r] == k).float().mean() > 0.9


def test_sample_pdf_proportional_and_within_bins():
    torch.manual_seed(1)
    bins = torch.tensor([[0.0, 1.0, 3.0, 4.0]])
    w = torch.tensor([[1.0, 0.0, 3.0]])
    t = sample_pdf(bins, w, 4000, jitter=True)
    assert (t >= 0).all() and (t <= 4).all()
    frac_last = ((t >= 3) & (t <= 4)).float().mean().item()
    assert abs(frac_last - 0.75) < 0.03
    assert ((t > 1.01) & (t < 2.99)).float().mean() < 0.01
    t = sample_pdf(bins, w, 8, jitter=False)
    assert (t[:, 1:] >= t[:, :-1]).all()
