"""Fixed sinusoidal positional encoding gamma(x) with its analytic Jacobian.

Without the Jacobian, gamma(x) and its backward go through one compiled pass each
(`kernels/encoding.cpp`, which also holds `sdf_grad_assembly.py`'s) where that applies;
`positional_encoding_reference` is the tensor-op form (a broadcast product, sin, cos, a
concatenation and their backwards: ~4x the time of the kernel's passes)."""
from __future__ import annotations

import math

import torch
from torch.autograd.function import once_differentiable

from nicer_stream.model.cpp_kernel import CppKernel

# -ffast-math: sin and cos from glibc's vector library (within a few ulp of torch's).
ENCODING_KERNEL = CppKernel("nicer_stream_encoding", "encoding.cpp", ["-O3", "-fopenmp", "-ffast-math", "-march=native"])


def frequencies(levels: int, dtype: torch.dtype, device: torch.device | str = "cpu") -> torch.Tensor:
    """f_l = 2^l pi (L,): the encoding's frequencies, the same values in every path."""
    return (2.0 ** torch.arange(levels, dtype=dtype, device=device)) * math.pi


def encoding_dim(levels: int, d: int = 3) -> int:
    """Output width of `positional_encoding` for `levels` frequencies of a d-vector."""
    return d + 2 * d * levels


class _Encoding(torch.autograd.Function):
    """apply(x (N, 3), levels) -> gamma(x) (N, 3 + 6 levels) through the compiled kernel; the
    backward reads sin and cos back from the encoding."""

    @staticmethod
    def forward(ctx, x: torch.Tensor, levels: int):
        freqs = frequencies(levels, x.dtype)
        enc = ENCODING_KERNEL.module().positional_encode(x.detach(), freqs)
        ctx.save_for_backward(enc, freqs)
        return enc

    @staticmethod
    @once_differentiable  # a double backward through it raises rather than being silently wrong
    def backward(ctx, g: torch.Tensor):
        enc, freqs = ctx.saved_tensors
        return ENCODING_KERNEL.module().positional_adjoint(enc, g, freqs), None


def positional_encoding(x: torch.Tensor, levels: int, with_tangent: bool = False):
    """gamma(x) = [x, sin(2^k pi x), cos(2^k pi x)]_{k<levels}.

    x: (N, d). Returns (N, d*(1+2L)) and, if `with_tangent`, the Jacobian
    (N, d, d*(1+2L)) whose row j is d gamma / d x_j. Differentiable in x either way.
    """
    if not with_tangent and x.dim() == 2 and x.shape[1] == 3 and ENCODING_KERNEL.available(x):
        return _Encoding.apply(x, levels)
    return positional_encoding_reference(x, levels, with_tangent)


def positional_encoding_reference(x: torch.Tensor, levels: int, with_tangent: bool = False):
    """`positional_encoding` in tensor ops (any d; the only path for the Jacobian)."""
    n, d = x.shape
    freqs = frequencies(levels, x.dtype, x.device)
    xf = x[:, None, :] * freqs[:, None]  # (N, L, d)
    s, c = torch.sin(xf), torch.cos(xf)
    enc = torch.cat([x, s.reshape(n, -1), c.reshape(n, -1)], dim=-1)
    if not with_tangent:
        return enc
    eye = torch.eye(d, dtype=x.dtype, device=x.device)  # d x_i / d x_j
    ds = (c * freqs[:, None])[:, None, :, :] * eye[None, :, None, :]  # (N, j, L, i)
    dc = (-s * freqs[:, None])[:, None, :, :] * eye[None, :, None, :]
    jac = torch.cat([eye.expand(n, d, d), ds.reshape(n, d, -1), dc.reshape(n, d, -1)], dim=-1)
    return enc, jac


def encoding_grad(enc: torch.Tensor, u: torch.Tensor, levels: int, d: int = 3) -> torch.Tensor:
    """J u for gamma's Jacobian J (N, d, E) at the points that gave `enc` (N, E), without forming J:
    u (N, E) = d f / d gamma -> d f / d x (N, d) = u_x + sum_k 2^k pi (cos_k u_sin,k - sin_k u_cos,k).
    Differentiable in `u` and (through `enc`) in x."""
    n = enc.shape[0]
    freqs = frequencies(levels, enc.dtype, enc.device)
    s = enc[:, d:d + d * levels].reshape(n, levels, d)
    c = enc[:, d + d * levels:].reshape(n, levels, d)
    u_s = u[:, d:d + d * levels].reshape(n, levels, d)
    u_c = u[:, d + d * levels:].reshape(n, levels, d)
    return u[:, :d] + ((c * u_s - s * u_c) * freqs[:, None]).sum(1)


if __name__ == "__main__":  # `make setup` builds the kernel once, so the first run does not wait for it
    print("encoding kernel:", "built" if ENCODING_KERNEL.available(torch.zeros(1)) else "not available (pure-torch path)")
