"""The SDF's spatial gradient assembled from its parts: one node instead of ~25.

`GeometryField` gets, from each geometry MLP i, u_i = d s_i / d h_i (N, P + F_i) for its input
h_i = [gamma(x), grid features_i] (`sdf_grad_mlp.py`), and from each grid its Jacobian
J_i = d features_i / d x (N, 3, F_i). The gradient is J u, contracted part by part:

    grad = encoding_grad(gamma(x), sum_i u_i[:, :P]) + sum_i J_i u_i[:, P:]

(the sphere's term is added by the caller). Its adjoint, for g = dL/d grad (N, 3):
dL/dJ_i = g u_i[:, P:]^T, dL/du_i[:, P:] = J_i^T g, dL/du_i[:, :P] = the encoding's Jacobian
applied to g (the same for every part), and dL/d gamma(x) at the sin and cos columns
-g_k f_l a_cos,lk and g_k f_l a_sin,lk with a = sum_i u_i[:, :P].

`kernels/encoding.cpp` computes both in one pass each over the points; in tensor ops
(`assemble_reference`, the path on a GPU or without the kernel) the backward alone took four
(N, 3, F) temporaries and ~8 ms of a `fast` mapping iteration's 110.
"""
from __future__ import annotations

import torch
from torch.autograd.function import once_differentiable

from nicer_stream.model.positional import ENCODING_KERNEL as _KERNEL, encoding_grad, frequencies

Part = tuple[torch.Tensor, torch.Tensor]  # (u (N, P + F), J (N, 3, F))


def _contract(jac: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
    """jac (N, 3, F), u (N, F) -> jac u (N, 3). As a product and a sum: `bmm` over N tiny
    matrices, with its backward, took 1.6-2x as long here."""
    return (jac * u[:, None, :]).sum(-1)


def assemble_reference(pe: torch.Tensor, levels: int, parts: list[Part]) -> torch.Tensor:
    """The assembly in tensor ops (autograd differentiates it): pe (N, P) = gamma(x) with
    `levels` frequencies, parts [(u_i, J_i)] -> grad (N, 3) without the sphere's term."""
    p = pe.shape[1]
    u_pe = parts[0][0][:, :p]
    grad = _contract(parts[0][1], parts[0][0][:, p:])
    for u, jac in parts[1:]:
        u_pe = u_pe + u[:, :p]
        grad = grad + _contract(jac, u[:, p:])
    return grad + encoding_grad(pe, u_pe, levels)


class SdfGradAssembly(torch.autograd.Function):
    """apply(pe, levels, u_0, J_0, u_1, J_1, ...) -> grad (N, 3) through the compiled kernel."""

    @staticmethod
    def forward(ctx, pe: torch.Tensor, levels: int, *flat: torch.Tensor):
        pe = pe.contiguous()
        us = [t.contiguous() for t in flat[0::2]]
        jacs = [t.contiguous() for t in flat[1::2]]
        freqs = frequencies(levels, pe.dtype)
        ctx.save_for_backward(pe, freqs, *us, *jacs)
        return _KERNEL.module().assemble_forward(pe, us, jacs, freqs)

    @staticmethod
    @once_differentiable  # a double backward through it raises rather than being silently wrong
    def backward(ctx, g: torch.Tensor):
        pe, freqs, *rest = ctx.saved_tensors
        k = len(rest) // 2
        us, jacs = rest[:k], rest[k:]
        need = list(ctx.needs_input_grad[2:])
        out = _KERNEL.module().assemble_backward(pe, us, jacs, g.contiguous(), freqs, ctx.needs_input_grad[0], need)
        grads = [t if n else None for t, n in zip(out[1:], need)]
        return (out[0] if ctx.needs_input_grad[0] else None), None, *grads


def kernel_applies(pe: torch.Tensor, parts: list[Part]) -> bool:
    """True when every tensor can go through the kernel (CPU, one float dtype, built)."""
    tensors = [pe] + [t for part in parts for t in part]
    return _KERNEL.available(pe) and all(t.dtype == pe.dtype and t.device == pe.device for t in tensors)


def assemble_sdf_grad(pe: torch.Tensor, levels: int, parts: list[Part]) -> torch.Tensor:
    """d s / d x (N, 3) without the sphere's term, from gamma(x) (N, P) and the parts
    [(u_i (N, P + F_i), J_i (N, 3, F_i))]: the compiled kernel where it applies, else the
    reference; differentiable in every input either way."""
    if kernel_applies(pe, parts):
        return SdfGradAssembly.apply(pe, levels, *[t for part in parts for t in part])
    return assemble_reference(pe, levels, parts)
