"""Robust per-channel penalties for the colour residuals (RGB rendering, warping, tracking).

A real camera's images blur and its rolling shutter shears them: some residuals stay large
whatever the pose and the map, and must not dominate the fit.
"""
from __future__ import annotations

import torch


def huber(residual: torch.Tensor, delta: float) -> torch.Tensor:
    """Huber's penalty, elementwise on any shape: r^2 / 2 where |r| <= delta, else
    delta * (|r| - delta / 2) (continuous, with a continuous first derivative)."""
    a = residual.abs()
    return torch.where(a <= delta, 0.5 * residual * residual, delta * (a - 0.5 * delta))


def robust_l1(residual: torch.Tensor, delta: float = 0.0) -> torch.Tensor:
    """(..., C) residuals -> (...,) per-ray penalty summed over channels: the L1 norm (the
    paper's) when delta <= 0, else `huber / delta`, which equals |r| - delta / 2 beyond delta
    (so a term's weight keeps its L1 meaning) and is quadratic, with a vanishing gradient, near 0."""
    if delta <= 0:
        return residual.abs().sum(-1)
    return huber(residual, delta).sum(-1) / delta


def huber_weights(residual: torch.Tensor, delta: float) -> torch.Tensor:
    """Huber's IRLS weights, elementwise: 1 inside |r| <= delta, delta / |r| outside (the
    weighted squares' gradient is then Huber's)."""
    return (delta / residual.abs().clamp_min(1e-12)).clamp(max=1.0)
