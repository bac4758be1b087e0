import torch

from nicer_stream.losses.photometric import masked_mean, rgb_l1


def test_rgb_l1_known_value_is_mean_of_per_ray_l1_norm():
    pred = torch.tensor([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    target = torch.tensor([[0.1, 0.2, 0.3], [1.0, 0.5, 1.0]])
    # per-ray |.|_1 = 0.6 and 0.5
    assert torch.isclose(rgb_l1(pred, target), torch.tensor(0.55))


def test_rgb_l1_mask_ignores_rays_even_non_finite():
    pred = torch.tensor([[0.0, 0.0, 0.0], [float("nan"), 5.0, 5.0]], requires_grad=True)
    target = torch.tensor([[0.1, 0.2, 0.3], [0.0, 0.0, 0.0]])
    loss = rgb_l1(pred, target, torch.tensor([True, False]))
    assert torch.isclose(loss, torch.tensor(0.6))
    loss.backward()
    assert torch.isfinite(pred.grad).all() and (pred.grad[1] == 0).all()


def test_empty_mask_gives_zero_not_nan():
    pred = torch.rand(4, 3, requires_grad=True)
    loss = rgb_l1(pred, torch.rand(4, 3), torch.zeros(4, dtype=torch.bool))
    assert loss.item() == 0.0
    loss.backward()  # still attached to the graph
    assert masked_mean(torch.zeros(0)).item() == 0.0


def test_rgb_loss_with_huber_is_quadratic_near_zero_and_l1_less_half_delta_beyond():
    pred = torch.zeros(2, 3)
    target = torch.tensor([[0.01, 0.0, -0.02], [0.5, -0.6, 0.7]])
    d = 0.05
    per_ray = [(0.01**2 + 0.02**2) / (2 * d), 1.8 - 3 * d / 2]
    assert torch.isclose(rgb_l1(pred, target, huber_delta=d), torch.tensor(sum(per_ray) / 2))
    assert torch.isclose(rgb_l1(pred, target, huber_delta=0.0), rgb_l1(pred, target))
