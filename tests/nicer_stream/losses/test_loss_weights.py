import dataclasses

import pytest
import torch

from nicer_stream.losses.weights import LossTerms, LossWeights, total_loss


def test_defaults_are_paper_eq12_and_frozen():
    w = LossWeights()
    assert (w.rgb, w.warp, w.flow, w.depth, w.normal_l1, w.normal_angular, w.eikonal) == (
        1.0, 0.5, 0.001, 0.1, 0.05, 0.05, 0.1,
    )
    with pytest.raises(dataclasses.FrozenInstanceError):
        w.rgb = 2.0


def test_weighted_sum_of_present_terms_only():
    terms = LossTerms(rgb=torch.tensor(2.0), flow=torch.tensor(100.0), eikonal=torch.tensor(3.0))
    assert torch.isclose(total_loss(terms), torch.tensor(2.0 + 0.1 + 0.3))
    custom = LossWeights(rgb=0.0, flow=1.0, eikonal=0.0)
    assert torch.isclose(total_loss(terms, custom), torch.tensor(100.0))


def test_every_term_is_weighted_by_its_own_field():
    names = [f.name for f in dataclasses.fields(LossTerms)]
    assert names == [f.name for f in dataclasses.fields(LossWeights)]
    for i, name in enumerate(names):
        w = LossWeights(**{n: float(j + 1) for j, n in enumerate(names)})
        assert total_loss(LossTerms(**{name: torch.tensor(1.0)}), w).item() == i + 1


def test_no_terms_is_zero_and_gradients_flow():
    assert total_loss(LossTerms()).item() == 0.0
    x = torch.tensor(1.0, requires_grad=True)
    total_loss(LossTerms(warp=3 * x, depth=x)).backward()
    assert torch.isclose(x.grad, torch.tensor(0.5 * 3 + 0.1))
