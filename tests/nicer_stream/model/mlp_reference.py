"""The tests' reference for `GeometryMLP`: its function through autograd over plain ops, with the
forward-mode tangent rows (moved here from the model: only the tests use it)."""
from __future__ import annotations

import torch
import torch.nn.functional as F

from nicer_stream.model.softplus import SOFTPLUS_BETA


def reference_forward(mlp, h: torch.Tensor, tangent: torch.Tensor | None = None):
    """(out, tangent @ d out / d h) of `mlp` (a GeometryMLP) at h (N, in); tangent (N, T, in) or None."""
    for i, layer in enumerate(mlp.layers):
        h = F.linear(h, layer.weight, layer.bias)
        if tangent is not None:
            tangent = tangent @ layer.weight.t()
        if i < len(mlp.layers) - 1:
            if tangent is not None:
                tangent = tangent * torch.sigmoid(SOFTPLUS_BETA * h)[:, None, :]
            # softplus(beta h) / beta written as logaddexp(beta h, 0): the same function,
            # 2x faster than F.softplus on CPU (and ~14x faster than its beta != 1 path).
            h = torch.logaddexp(h * SOFTPLUS_BETA, h.new_zeros(())) / SOFTPLUS_BETA
    return h, tangent
