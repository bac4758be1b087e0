"""Eikonal regulariser (paper Sec. 3.3): SDF gradients should have unit norm."""
from __future__ import annotations

import torch


def eikonal_loss(grad: torch.Tensor) -> torch.Tensor:
    """Mean of (|grad|_2 - 1)^2 over (N, 3) SDF gradients. Returns a 0-dim tensor."""
    return ((grad.norm(dim=-1) - 1.0) ** 2).mean()

