"""The geometry MLPs' activation: softplus with beta = 100 (VolSDF/MonoSDF)."""
from __future__ import annotations

import torch

from nicer_stream.numerics import exp_neg

SOFTPLUS_BETA = 100.0  # VolSDF/MonoSDF geometry activation


def softplus_beta(z: torch.Tensor, beta: float = SOFTPLUS_BETA) -> torch.Tensor:
    """softplus(beta z) / beta as relu(beta z) + log(1 + exp(-|beta z|)): the same function,
    ~5x faster than logaddexp/log1p on this CPU (their kernels are not vectorised here)."""
    bz = z * beta
    if not (torch.is_grad_enabled() and z.requires_grad):
        # In place where no graph needs the intermediates: 2 allocations instead of 9.
        t = exp_neg(bz.abs()).add_(1).log_()
        return t.add_(bz.relu_()).div_(beta)
    return (torch.relu(bz) + torch.log(1 + exp_neg(bz.abs()))) / beta
