import torch

from nicer_stream.losses.flow import flow_loss


def test_zero_when_rendered_correspondence_equals_prior():
    g = torch.Generator().manual_seed(0)
    uv = torch.rand(50, 2, generator=g, dtype=torch.float64) * 100
    flow = torch.randn(50, 2, generator=g, dtype=torch.float64) * 5
    valid = torch.ones(50, dtype=torch.bool)
    assert flow_loss(uv, uv + flow, flow, valid).item() < 1e-9


def test_known_value_and_masked_terms_ignored():
    uv = torch.zeros(3, 2)
    flow = torch.zeros(3, 2)
    uv_dst = torch.tensor([[1.0, -2.0], [0.5, 0.5], [1e6, 1e6]])
    valid = torch.tensor([True, True, False])
    # |(1,-2)|_1 = 3, |(0.5,0.5)|_1 = 1 -> mean 2; the huge masked one is ignored.
    assert torch.isclose(flow_loss(uv, uv_dst, flow, valid), torch.tensor(2.0))


def test_gradient_reaches_rendered_pixels():
    uv_dst = torch.tensor([[2.0, 1.0]], requires_grad=True)
    flow_loss(torch.zeros(1, 2), uv_dst, torch.zeros(1, 2), torch.tensor([True])).backward()
    assert torch.equal(uv_dst.grad, torch.tensor([[1.0, 1.0]]))
