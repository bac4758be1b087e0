"""Eikonal regulariser (paper Sec. 3.3): SDF gradients should have unit norm."""
from __future__ import annotations

from typing import Callable

import torch


def eikonal_loss(grad: torch.Tensor) -> torch.Tensor:
    """Mean of (|grad|_2 - 1)^2 over (N, 3) SDF gradients. Returns a 0-dim tensor."""
    return ((grad.norm(dim=-1) - 1.0) ** 2).mean()


def sdf_gradient(
    sdf_fn: Callable[[torch.Tensor], torch.Tensor], x: torch.Tensor, create_graph: bool = True
) -> torch.Tensor:
    """(N, 3) gradient of `sdf_fn` ((N, 3) points -> (N,) SDF) at points `x` (N, 3).

    With create_graph=True the result stays differentiable, so an eikonal loss
    on it trains the SDF's parameters.
    """
    x = x.detach().requires_grad_(True)
    with torch.enable_grad():
        s = sdf_fn(x)
        (grad,) = torch.autograd.grad(s.sum(), x, create_graph=create_graph)
    return grad
