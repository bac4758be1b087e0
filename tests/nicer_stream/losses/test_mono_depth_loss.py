import torch

from nicer_stream.losses.mono_depth import mono_depth_loss, scale_shift_lstsq


def _data(n=500, seed=3):
    g = torch.Generator().manual_seed(seed)
    pred = 0.5 + 4 * torch.rand(n, generator=g)
    return pred, g


def test_lstsq_recovers_scale_and_shift_exactly():
    pred, _ = _data()
    w, q = scale_shift_lstsq(pred, 0.37 * pred - 1.2)
    assert abs(w.item() - 0.37) < 1e-5 and abs(q.item() + 1.2) < 1e-5


def test_lstsq_mask_ignores_outliers():
    pred, g = _data()
    target = 2.5 * pred + 0.3
    outliers = torch.rand(len(pred), generator=g) < 0.2
    target[outliers] = 100 * torch.rand(int(outliers.sum()), generator=g)
    w, q = scale_shift_lstsq(pred, target, ~outliers)
    assert abs(w.item() - 2.5) < 1e-5 and abs(q.item() - 0.3) < 1e-5
    w_all, _ = scale_shift_lstsq(pred, target)
    assert abs(w_all.item() - 2.5) > 0.1  # the mask is what made it exact


def test_lstsq_matches_numpy_polyfit_on_noisy_data():
    pred, g = _data()
    target = 1.7 * pred + 0.2 + 0.3 * torch.randn(len(pred), generator=g)
    import numpy as np

    w_ref, q_ref = np.polyfit(pred.double().numpy(), target.double().numpy(), 1)
    w, q = scale_shift_lstsq(pred, target)
    assert abs(w.item() - w_ref) < 1e-5 and abs(q.item() - q_ref) < 1e-5


def test_loss_zero_when_aligned_and_no_gradient_through_fit():
    pred, _ = _data()
    pred = pred.clone().requires_grad_(True)
    target = (3.0 * pred + 0.5).detach()
    loss = mono_depth_loss(pred, target)
    assert loss.item() < 1e-8
    # Perturb one depth: the gradient is 2 w (w d + q - t) / N for that ray only,
    # i.e. (w, q) are constants (MonoSDF), not differentiated.
    p2 = pred.detach().clone()
    p2[0] += 0.1
    p2.requires_grad_(True)
    loss = mono_depth_loss(p2, target)
    loss.backward()
    w, q = scale_shift_lstsq(p2, target)
    expected = 2 * w * (w * p2[0] + q - target[0]) / len(p2)
    assert torch.isclose(p2.grad[0], expected.detach(), rtol=1e-4)


def test_fixed_scale_shift_known_value():
    pred = torch.tensor([0.1, 0.2])
    prior = torch.tensor([2.0, 3.0])
    # (20*0.1 - 2)^2 = 0, (20*0.2 - 3)^2 = 1 -> mean 0.5
    assert torch.isclose(mono_depth_loss(pred, prior, fixed_scale_shift=(20.0, 0.0)), torch.tensor(0.5))


def test_degenerate_inputs_give_zero_without_nan():
    pred = torch.tensor([1.0, 2.0, 3.0], requires_grad=True)
    prior = torch.tensor([4.0, 1.0, 7.0])
    one = torch.tensor([True, False, False])
    none = torch.zeros(3, dtype=torch.bool)
    for mask in (one, none):
        loss = mono_depth_loss(pred, prior, mask)
        assert loss.item() == 0.0
        loss.backward()
        assert torch.isfinite(pred.grad).all()
        w, q = scale_shift_lstsq(pred, prior, mask)
        assert torch.isfinite(w) and torch.isfinite(q)
    const = torch.full((3,), 2.0)
    assert mono_depth_loss(const, prior).item() == 0.0
    assert torch.isfinite(torch.stack(scale_shift_lstsq(const, prior))).all()


def test_non_finite_prior_is_ignored():
    pred, _ = _data(50)
    prior = 2.0 * pred
    prior[3] = float("nan")
    loss = mono_depth_loss(pred, prior)
    assert torch.isfinite(loss) and loss.item() < 1e-8
