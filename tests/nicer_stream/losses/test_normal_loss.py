import torch
import torch.nn.functional as F

from nicer_stream.losses.normal import normal_loss


def test_zero_for_equal_normals_even_if_pred_not_unit():
    n = F.normalize(torch.randn(20, 3, generator=torch.Generator().manual_seed(1)), dim=-1)
    l1, ang = normal_loss(0.3 * n, n)  # rendered normals are weighted sums, not unit
    assert l1.item() < 1e-6 and ang.item() < 1e-6


def test_orthogonal_normals_known_values():
    l1, ang = normal_loss(torch.tensor([[1.0, 0.0, 0.0]]), torch.tensor([[0.0, 1.0, 0.0]]))
    assert torch.isclose(l1, torch.tensor(2.0)) and torch.isclose(ang, torch.tensor(1.0))


def test_opposite_normals_and_mask():
    pred = torch.tensor([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    prior = torch.tensor([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    l1, ang = normal_loss(pred, prior)
    assert torch.isclose(l1, torch.tensor(1.0)) and torch.isclose(ang, torch.tensor(1.0))
    l1, ang = normal_loss(pred, prior, torch.tensor([False, True]))
    assert l1.item() == 0.0 and ang.item() == 0.0


def test_zero_length_prediction_stays_finite():
    pred = torch.zeros(2, 3, requires_grad=True)
    l1, ang = normal_loss(pred, torch.tensor([[0.0, 0.0, -1.0]] * 2))
    (l1 + ang).backward()
    assert torch.isfinite(l1) and torch.isfinite(pred.grad).all()
