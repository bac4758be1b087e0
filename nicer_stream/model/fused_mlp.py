"""TangentMLP forward and backward in one autograd node, with the backward written out.

Autograd over the reference `TangentMLP.forward` records ~10 nodes per layer and keeps
recomputing what the forward already had (the softplus derivative is the sigmoid the
tangent needed). Here the value row and the three tangent rows of each point go through
a layer as one (4N, in) @ (in, out) product, the activation is evaluated once, and the
backward reuses the saved sigmoid:

    z = h W^T + b,  Tz = T W^T,  s = sigmoid(beta z),  h' = softplus_beta(z),  T' = Tz * s
    dL/dTz = G' * s
    dL/dz  = g' * s + beta s (1 - s) * sum_j G'_j * Tz_j
    dL/dW  = [dL/dz; dL/dTz]^T [h; T],   dL/d[h; T] = [dL/dz; dL/dTz] W

The reference path stays in `TangentMLP.reference_forward`; tests compare both (values,
gradients, gradcheck in float64).
"""
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


class FusedTangentMLP(torch.autograd.Function):
    """apply(h (N, in), T (N, 3, in), n_layers, W_0, b_0, ..., W_{n-1}, b_{n-1}) -> (out (N, o), T_out (N, 3, o)).

    Softplus(beta) between layers, none after the last."""

    @staticmethod
    def forward(ctx, h: torch.Tensor, tangent: torch.Tensor, n: int, *params: torch.Tensor):
        weights, biases = params[0::2], params[1::2]
        x = torch.cat([h[:, None], tangent], 1)  # (N, 4, in): value row, then the 3 tangent rows
        saved = []
        for i, (w, b) in enumerate(zip(weights, biases)):
            inp = x
            x = inp @ w.t()  # (N, 4, out)
            if i < n - 1:
                z = x[:, 0] + b
                s = torch.sigmoid(z * SOFTPLUS_BETA)
                tz = x[:, 1:]
                saved += [inp, s, tz]
                x = torch.empty_like(x)  # written in place: no cat of the value and tangent rows
                x[:, 0] = softplus_beta(z)
                torch.mul(tz, s[:, None], out=x[:, 1:])
            else:
                saved.append(inp)
                x[:, 0] += b
        ctx.n = n
        ctx.save_for_backward(*saved, *weights)
        out = x[:, 0].contiguous()
        return out, x[:, 1:].contiguous()

    @staticmethod
    def backward(ctx, g_out: torch.Tensor, g_tan: torch.Tensor):
        n = ctx.n
        saved = ctx.saved_tensors
        weights = saved[-n:]
        acts = saved[:-n]
        need_params = any(ctx.needs_input_grad[3:])
        grads_w, grads_b = [None] * n, [None] * n
        if g_out is None:
            g_out = torch.zeros(g_tan.shape[0], g_tan.shape[2], dtype=g_tan.dtype, device=g_tan.device)
        if g_tan is None:
            g_tan = torch.zeros(g_out.shape[0], 3, g_out.shape[1], dtype=g_out.dtype, device=g_out.device)
        g = torch.cat([g_out[:, None], g_tan], 1)  # (N, 4, out) gradient w.r.t. [z; Tz] of the last layer
        pos = len(acts)
        for i in range(n - 1, -1, -1):
            if i == n - 1:
                inp = acts[pos - 1]
                pos -= 1
            else:
                inp, s, tz = acts[pos - 3:pos]
                pos -= 3
                # g holds dL/d[h'; T'] of layer i: turn it into dL/d[z; Tz].
                # g is the fresh product of the layer above: updated in place.
                g_s = (g[:, 1:] * tz).sum(1)
                g[:, 0] = g[:, 0] * s + g_s * (SOFTPLUS_BETA * s * (1 - s))
                g[:, 1:] *= s[:, None]
            w = weights[i]
            if need_params:
                flat_g = g.reshape(-1, g.shape[-1])
                grads_w[i] = flat_g.t() @ inp.reshape(-1, inp.shape[-1])
                grads_b[i] = g[:, 0].sum(0)
            g = g @ w  # dL/d[h; T] of layer i's input
        params = [p for pair in zip(grads_w, grads_b) for p in pair]
        return (g[:, 0], g[:, 1:], None, *params)
