"""Beta: Eq. 8 adaptive transform, voxel counting, fixed and global modes."""
import math

import pytest
import torch

from nicer_stream.config import RenderConfig
from nicer_stream.render.beta import BetaField, adaptive_beta
from nicer_stream.errors import UserError

C0, C1, C2 = 1.208e-2, 6.26471e-6, 2.3e-3  # paper Sec. 3.4


def test_adaptive_beta_paper_constants():
    cfg = RenderConfig()
    counts = torch.tensor([0.0, 1e5, 1e6], dtype=torch.float64)
    got = adaptive_beta(counts, cfg.beta_c0, cfg.beta_c1, cfg.beta_c2)
    expect = [C0 * math.exp(-C1 * c) + C2 for c in (0.0, 1e5, 1e6)]
    assert torch.allclose(got, torch.tensor(expect, dtype=torch.float64), rtol=1e-12)
    assert abs(got[0].item() - (C0 + C2)) < 1e-12
    assert abs(got[2].item() - C2) < 1e-4  # saturates at c2


def test_count_goes_to_the_right_voxel():
    cfg = RenderConfig(beta_voxels=4, beta_count_weight=2.0)
    bf = BetaField(cfg)
    # Voxel (i, j, k) covers [-1 + i/2, -1 + (i+1)/2) per axis.
    x = torch.tensor([[-0.9, -0.1, 0.6], [-0.9, -0.1, 0.6], [1.0, 1.0, 1.0], [-1.0, 0.0, 0.49]])
    bf.count(x)
    c = bf.counts.reshape(4, 4, 4)
    assert c[0, 1, 3] == 4.0  # two samples x weight 2
    assert c[3, 3, 3] == 2.0  # the upper boundary belongs to the last voxel
    assert c[0, 2, 2] == 2.0
    assert c.sum() == 8.0
    beta = bf(x)
    assert beta.shape == (4,)
    assert torch.allclose(beta[0].double(), adaptive_beta(torch.tensor(4.0, dtype=torch.float64), C0, C1, C2))
    # An unvisited voxel keeps the initial beta.
    assert torch.allclose(bf(torch.tensor([[0.9, -0.9, 0.0]])), torch.tensor([C0 + C2]))
    centres, betas = bf.voxel_betas()
    assert centres.shape == (3, 3) and betas.shape == (3,)
    assert torch.allclose(centres[0], torch.tensor([-0.75, -0.25, 0.75]))


def test_counts_are_saved_with_the_model():
    bf = BetaField(RenderConfig(beta_voxels=2))
    bf.count(torch.zeros(3, 3))
    assert "counts" in bf.state_dict()
    other = BetaField(RenderConfig(beta_voxels=2))
    other.load_state_dict(bf.state_dict())
    assert torch.equal(other.counts, bf.counts)


def test_fixed_mode():
    bf = BetaField(RenderConfig(beta_mode="fixed", beta_fixed=0.02))
    bf.count(torch.zeros(5, 3))  # counting does not affect a fixed beta
    b = bf(torch.rand(7, 3))
    assert b.dim() == 0 and abs(b.item() - 0.02) < 1e-9
    assert not any(p.requires_grad for p in bf.parameters())


def test_global_mode_is_learnable():
    bf = BetaField(RenderConfig(beta_mode="global", beta_fixed=0.05))
    b = bf(torch.rand(7, 3))
    assert b.dim() == 0 and abs(b.item() - 0.05) < 1e-7
    learnable = [p for p in bf.parameters() if p.requires_grad]
    assert len(learnable) == 1
    opt = torch.optim.SGD(learnable, lr=0.1)
    bf(torch.zeros(1, 3)).backward()  # minimise beta
    opt.step()
    assert bf(torch.zeros(1, 3)).item() < 0.05


def test_unknown_mode_rejected():
    with pytest.raises(UserError, match="render.beta_mode must be one of .adaptive., .global., .fixed., got .local."):
        BetaField(RenderConfig(beta_mode="local"))
