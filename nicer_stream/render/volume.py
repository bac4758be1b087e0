"""Volume-rendering weights and accumulation (Eqs. 5-6)."""
from __future__ import annotations

import torch

from nicer_stream.numerics import exp_neg


def render_weights(sigma: torch.Tensor, deltas: torch.Tensor) -> torch.Tensor:
    """(R, S) densities and interval lengths -> (R, S) weights T_i * alpha_i.

    T_i = exp(-sum_{j<i} sigma_j delta_j): the cumsum form, whose backward is far
    cheaper on CPU than that of cumprod(1 - alpha).
    """
    tau = sigma * deltas
    return _transmittance(tau) * (1 - exp_neg(tau))


def transmittance(sigma: torch.Tensor, deltas: torch.Tensor) -> torch.Tensor:
    """(R, S) densities and interval lengths -> (R, S) T_i, the light reaching sample i (1 at the first)."""
    return _transmittance(sigma * deltas)


def _transmittance(tau: torch.Tensor) -> torch.Tensor:
    acc = torch.cumsum(tau, dim=-1)
    return exp_neg(torch.cat([torch.zeros_like(acc[:, :1]), acc[:, :-1]], dim=-1))


def accumulate(weights: torch.Tensor, values: torch.Tensor) -> torch.Tensor:
    """(R, S) weights, (R, S, C) or (R, S) values -> (R, C) or (R,) sums."""
    if values.dim() == 2:
        return (weights * values).sum(-1)
    return (weights[..., None] * values).sum(-2)
