"""Huber's penalty and the Huber-smoothed L1 of the colour residuals."""
import torch

from nicer_stream.losses.robust import huber, huber_weights, robust_l1


def test_huber_is_half_the_square_below_the_threshold_and_linear_above():
    d = 0.1
    r = torch.linspace(-d, d, 41, dtype=torch.float64)
    assert torch.allclose(huber(r, d), 0.5 * r * r)
    t = torch.tensor([0.0, 0.05, 0.3, 2.0], dtype=torch.float64)
    for sign in (1.0, -1.0):  # beyond the threshold each unit of |r| adds delta, on both sides
        assert torch.allclose(huber(sign * (d + t), d) - huber(torch.tensor(d, dtype=torch.float64), d), d * t)
    assert (huber(torch.tensor([2.0]), d) < 0.5 * 2.0**2).all()  # far less than the square


def test_huber_gradient_is_finite_and_continuous_at_the_threshold():
    d = 0.1
    r = torch.tensor([-5.0, -d, -d + 1e-6, 0.0, d - 1e-6, d, d + 1e-6, 5.0], dtype=torch.float64, requires_grad=True)
    (g,) = torch.autograd.grad(huber(r, d).sum(), [r])
    assert torch.isfinite(g).all()
    assert torch.allclose(g, r.detach().clamp(-d, d), atol=1e-6)  # r inside, delta * sign(r) outside
    # IRLS: weight * r is Huber's derivative
    assert torch.allclose(huber_weights(r.detach(), d) * r.detach(), g, atol=1e-6)


def test_huber_weights():
    w = huber_weights(torch.tensor([0.0, 0.01, -0.05, 0.2, -1.0]), 0.05)
    assert torch.allclose(w, torch.tensor([1.0, 1.0, 1.0, 0.25, 0.05]))


def test_robust_l1_is_l1_at_zero_delta_and_keeps_l1_slope_beyond_the_threshold():
    g = torch.Generator().manual_seed(0)
    res = torch.randn(50, 3, generator=g, dtype=torch.float64)
    assert torch.equal(robust_l1(res, 0.0), res.abs().sum(-1))
    d = 0.01
    big = res[(res.abs() > d).all(-1)]
    assert torch.allclose(robust_l1(big, d), big.abs().sum(-1) - 3 * d / 2)
    small = torch.full((4, 3), 0.004, dtype=torch.float64)
    assert torch.allclose(robust_l1(small, d), (0.5 * small**2 / d).sum(-1))
    x = res.clone().requires_grad_()
    (gr,) = torch.autograd.grad(robust_l1(x, d).sum(), [x])
    assert torch.isfinite(gr).all() and gr.abs().max() <= 1.0 + 1e-12  # never steeper than L1
