"""RGB rendering loss (paper Eq. 7) and the masked mean shared by all per-ray losses.

Per-ray losses use the L1 *norm* of the per-ray residual (sum over channels),
averaged over the rays that count, as MonoSDF normalises its L1 sums.
"""
from __future__ import annotations

import torch

from nicer_stream.losses.robust import robust_l1


def masked_mean(values: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
    """Mean of (..., N) `values` over (..., N) bool `mask` (all rays if None), along the last
    dimension: a 0-dim tensor for (N,) rays, one mean per row for (R, N).

    An empty selection gives 0 (still attached to the graph, so callers can sum it into a
    loss) instead of NaN. Rays outside the mask get zero gradient even if their values are
    non-finite.
    """
    if mask is None:
        return values.mean(-1) if values.numel() else values.sum(-1)
    mask = mask.to(torch.bool)
    kept = torch.where(mask, values, torch.zeros_like(values))
    return kept.sum(-1) / mask.sum(-1).clamp_min(1).to(values.dtype)


def rgb_l1(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor | None = None,
           huber_delta: float = 0.0) -> torch.Tensor:
    """Mean over rays of |pred - target|_1 (with `huber_delta` > 0: of the Huber-smoothed
    norm `robust.robust_l1`).

    pred, target: (N, 3) float RGB in [0, 1]. mask: (N,) bool or None (all rays).
    Returns a 0-dim tensor.
    """
    return masked_mean(robust_l1(pred - target, huber_delta), mask)
