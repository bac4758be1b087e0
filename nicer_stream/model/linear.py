"""Dense layers for the small MLPs: y = x W^T + b through oneDNN's float32 inner product on CPUs.

torch sends float32 `addmm`/`mm` on CPU to MKL, which on this AMD CPU runs our tall-skinny shapes
((16k, 71) x (71, 64)) at 50-125 GFLOP/s. oneDNN's inner product (`mkldnn::_linear_pointwise`, the
op torch's own compiler emits for CPU linears) runs them 2.5-3x faster in strict float32: the same
arithmetic class, results within float32 rounding of `addmm` (tests compare both). Reductions over
the batch (weight gradients, `x^T g`) stay with `mm`: the inner product is slower there.
Elsewhere (CUDA, float64, builds without oneDNN, NICER_STREAM_ONEDNN=0) the plain ops run.
"""
from __future__ import annotations

import os

import torch
from torch import nn


def onednn_available(t: torch.Tensor) -> bool:
    """True when `t` (a layer input) can go through oneDNN's float32 inner product."""
    return (t.device.type == "cpu" and t.dtype == torch.float32 and torch.backends.mkldnn.is_available()
            and _OP is not None and os.environ.get("NICER_STREAM_ONEDNN", "1") != "0")


def _find_op():
    try:
        return torch.ops.mkldnn._linear_pointwise
    except (AttributeError, RuntimeError):
        return None


_OP = _find_op()


def linear(x: torch.Tensor, w: torch.Tensor, b: torch.Tensor | None = None) -> torch.Tensor:
    """x (N, I), w (O, I), b (O,) or None -> x w^T + b (N, O), without autograd (for custom
    Functions and graph-free passes)."""
    if onednn_available(x) and x.shape[0] > 0:
        return _OP(x.detach().contiguous(), w.detach().contiguous(), None if b is None else b.detach(), "none", [], "")
    return linear_reference(x, w, b)


def linear_reference(x: torch.Tensor, w: torch.Tensor, b: torch.Tensor | None = None) -> torch.Tensor:
    """`linear` through torch's addmm/mm."""
    return torch.nn.functional.linear(x, w, b)


def matmul(x: torch.Tensor, w: torch.Tensor) -> torch.Tensor:
    """x (N, O), w (O, I) -> x w (N, I): the input gradient of `linear` (w^T is a small copy)."""
    if onednn_available(x) and x.shape[0] > 0:
        return linear(x, w.t().contiguous())
    return x @ w


class LinearFunction(torch.autograd.Function):
    """apply(x (N, I), w (O, I), b (O,)) -> x w^T + b with the analytic backward: dx = g w (oneDNN),
    dw = g^T x and db = sum g (torch)."""

    @staticmethod
    def forward(ctx, x: torch.Tensor, w: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        ctx.save_for_backward(x, w)
        return linear(x, w, b)

    @staticmethod
    def backward(ctx, g: torch.Tensor):
        x, w = ctx.saved_tensors
        gx = matmul(g, w) if ctx.needs_input_grad[0] else None
        gw = g.t() @ x if ctx.needs_input_grad[1] else None
        gb = g.sum(0) if ctx.needs_input_grad[2] else None
        return gx, gw, gb


class Linear(nn.Linear):
    """`nn.Linear` (same parameters and state-dict keys) whose product goes through `linear`."""

    def forward(self, x: torch.Tensor, rows: int | None = None) -> torch.Tensor:
        """x (N, I) -> (N, O), or only the first `rows` outputs (the weight's first rows)."""
        w, b = (self.weight, self.bias) if rows is None else (self.weight[:rows], self.bias[:rows])
        if x.dim() != 2 or not onednn_available(x):
            return linear_reference(x, w, b)
        if torch.is_grad_enabled() and (x.requires_grad or w.requires_grad):
            return LinearFunction.apply(x, w, b)
        return linear(x, w, b)
