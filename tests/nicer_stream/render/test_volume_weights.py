"""render_weights / accumulate: Eq. 5-6 transmittance weights."""
import torch

from nicer_stream.render.volume import accumulate, render_weights


def test_hand_computed_three_samples():
    sigma = torch.tensor([[0.5, 2.0, 1.0]], dtype=torch.float64)
    delta = torch.tensor([[1.0, 0.5, 2.0]], dtype=torch.float64)
    alpha = [1 - torch.exp(-sigma[0, i] * delta[0, i]) for i in range(3)]
    T = [1.0, 1 - alpha[0], (1 - alpha[0]) * (1 - alpha[1])]  # T_i = prod_{j<i} (1 - alpha_j)
    expect = torch.stack([T[i] * alpha[i] for i in range(3)])[None]
    w = render_weights(sigma, delta)
    assert torch.allclose(w, expect, atol=1e-12)
    # Sum equals 1 - final transmittance.
    assert torch.allclose(w.sum(), 1 - T[2] * (1 - alpha[2]))


def test_bounds_and_sum_at_most_one():
    g = torch.Generator().manual_seed(0)
    sigma = torch.rand(64, 20, generator=g) * torch.logspace(-2, 3, 64)[:, None]
    delta = torch.rand(64, 20, generator=g) * 0.1
    w = render_weights(sigma, delta)
    assert (w >= 0).all() and (w <= 1).all()
    assert (w.sum(-1) <= 1 + 1e-6).all()


def test_empty_space_has_zero_weight():
    w = render_weights(torch.zeros(2, 5), torch.ones(2, 5))
    assert torch.equal(w, torch.zeros(2, 5))


def test_opaque_wall():
    sigma = torch.tensor([[0.0, 0.0, 1e4, 1e4, 0.0]])
    delta = torch.full((1, 5), 0.1)
    w = render_weights(sigma, delta)
    assert w[0, 2] > 0.999 and w[0, :2].abs().max() < 1e-9 and w[0, 3:].max() < 1e-6
    t = torch.tensor([[0.1, 0.2, 0.3, 0.4, 0.5]])
    assert abs(accumulate(w, t).item() - 0.3) < 1e-3


def test_accumulate_shapes_and_values():
    w = torch.tensor([[0.2, 0.5, 0.3]])
    v = torch.tensor([[[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]])
    assert torch.allclose(accumulate(w, v), torch.tensor([[0.5, 0.8]]))
    assert torch.allclose(accumulate(w, torch.tensor([[1.0, 2.0, 3.0]])), torch.tensor([2.1]))
