"""The SDF MLP's value and input gradient by reverse mode, forward and backward in one node.

Forward mode (the tests' `reference_forward`) pushes three tangent rows through every layer,
and its backward all four rows again: 12 row-products per layer. Only the tangent of output 0
(the SDF) is ever used, so one reverse sweep gives it instead: u = d out_0 / d h (N, in). The
caller contracts u with its inputs' Jacobians (grad = J u), part by part and without
materialising J (`GeometryField`). The backward differentiates the sweep analytically: 6
row-products per layer (4 when the weights are frozen), half the FLOPs.

Layers i = 0..n-1: z_i = h_i W_i^T + b_i, h_{i+1} = softplus_beta(z_i), s_i = sigmoid(beta z_i).
Reverse sweep:  u_{n-1} = W_{n-1}[0],  v_i = u_{i+1} * s_i,  u_i = v_i W_i,  grad = J u_0.
Its adjoint (bar = dL/d.), upwards from ubar_0 (the gradient arriving at u_0):
    vbar_i = ubar_i W_i^T,  Wbar_i += v_i^T ubar_i,  ubar_{i+1} = vbar_i * s_i,
    zbar_i += vbar_i * u_{i+1} * beta s_i (1 - s_i),  Wbar_{n-1}[0] += sum ubar_{n-1};
then the value path downwards as usual (zbar_i += hbar_{i+1} * s_i).

The reference is the tests' `reference_forward` (its tangent's column 0, against J u_0); tests
compare values and gradients and run gradcheck in float64.
"""
from __future__ import annotations

import torch

from nicer_stream.model.linear import linear, matmul
from nicer_stream.model.softplus import softplus_and_sigmoid, sweep_adjoint


class FusedSdfGradMLP(torch.autograd.Function):
    """apply(h (N, in), n_layers, W_0, b_0, ..., W_{n-1}, b_{n-1})
    -> (out (N, o), u (N, in)) with u = d out[:, 0] / d h.

    Softplus(beta) between layers, none after the last."""

    @staticmethod
    def forward(ctx, h: torch.Tensor, n: int, *params: torch.Tensor):
        weights, biases = params[0::2], params[1::2]
        hs, ss = [h], []
        x = h
        for w, b in zip(weights[:-1], biases[:-1]):
            z = linear(x, w, b)
            x, s = softplus_and_sigmoid(z)
            ss.append(s)
            hs.append(x)
        out = linear(x, weights[-1], biases[-1])
        # Reverse sweep for d out_0 / d h_i: u_{n-1} is the last layer's first row.
        vs, us = [None] * (n - 1), [None] * n
        u = weights[-1][0].expand(h.shape[0], -1)
        us[n - 1] = u
        for i in range(n - 2, -1, -1):
            v = u * ss[i]
            vs[i] = v
            u = matmul(v, weights[i])
            us[i] = u
        ctx.n = n
        ctx.save_for_backward(*hs, *ss, *vs, *us, *weights)
        return out, u

    @staticmethod
    def backward(ctx, g_out: torch.Tensor, g_u: torch.Tensor):
        n = ctx.n
        saved = ctx.saved_tensors
        hs = saved[:n]
        ss = saved[n:2 * n - 1]
        vs = saved[2 * n - 1:3 * n - 2]
        us = saved[3 * n - 2:4 * n - 2]
        weights = saved[4 * n - 2:]
        need_params = any(ctx.needs_input_grad[2:])
        grads_w = [torch.zeros_like(w) for w in weights] if need_params else [None] * n
        grads_b = [None] * n
        zbar_u: list[torch.Tensor | None] = [None] * (n - 1)
        if g_u is not None:
            ubar = g_u
            for i in range(n - 1):
                vbar = linear(ubar, weights[i])
                if need_params:
                    grads_w[i].addmm_(vs[i].t(), ubar)
                ubar, zbar_u[i] = sweep_adjoint(vbar, us[i + 1], ss[i])
            if need_params:
                grads_w[-1][0] += ubar.sum(0)
        # Value path, downwards.
        zbar = g_out if g_out is not None else None
        hbar = None
        for i in range(n - 1, -1, -1):
            if i < n - 1:
                if hbar is None:
                    zbar = zbar_u[i]
                else:
                    zbar = hbar * ss[i] if zbar_u[i] is None else torch.addcmul(zbar_u[i], hbar, ss[i])
            if zbar is None:
                hbar = None
                continue
            if need_params:
                grads_w[i].addmm_(zbar.t(), hs[i])
                grads_b[i] = zbar.sum(0)
            hbar = matmul(zbar, weights[i]) if (i > 0 or ctx.needs_input_grad[0]) else None
        if need_params:
            grads_b = [g if g is not None else torch.zeros_like(w[:, 0]) for g, w in zip(grads_b, weights)]
        params = [p for pair in zip(grads_w, grads_b) for p in pair]
        return (hbar, None, *params)

