"""Row gather whose backward is a plain `index_add_` (fast on CPU).

Autograd's default backward for `table[idx]` goes through an accumulating
`index_put_`, several times slower on CPU (docs/performance notes).
"""
from __future__ import annotations

import torch


class _GatherRows(torch.autograd.Function):
    @staticmethod
    def forward(ctx, table: torch.Tensor, idx: torch.Tensor) -> torch.Tensor:
        ctx.save_for_backward(idx)
        ctx.n_rows = table.shape[0]
        return table[idx]

    @staticmethod
    def backward(ctx, grad_out: torch.Tensor):
        (idx,) = ctx.saved_tensors
        c = grad_out.shape[-1]
        grad = torch.zeros(ctx.n_rows, c, dtype=grad_out.dtype, device=grad_out.device)
        grad.index_add_(0, idx.reshape(-1), grad_out.reshape(-1, c))
        return grad, None


def gather_rows(table: torch.Tensor, idx: torch.Tensor) -> torch.Tensor:
    """table (R, C), idx (...) long -> (..., C) rows, differentiable w.r.t. table."""
    if not table.requires_grad or not torch.is_grad_enabled():
        return table[idx]
    return _GatherRows.apply(table, idx)
