"""Fixed sinusoidal positional encoding gamma(x) with its analytic Jacobian."""
from __future__ import annotations

import math

import torch


def encoding_dim(levels: int, d: int = 3) -> int:
    """Output width of `positional_encoding` for `levels` frequencies of a d-vector."""
    return d + 2 * d * levels


def positional_encoding(x: torch.Tensor, levels: int, with_tangent: bool = False):
    """gamma(x) = [x, sin(2^k pi x), cos(2^k pi x)]_{k<levels}.

    x: (N, d). Returns (N, d*(1+2L)) and, if `with_tangent`, the Jacobian
    (N, d, d*(1+2L)) whose row j is d gamma / d x_j.
    """
    n, d = x.shape
    freqs = (2.0 ** torch.arange(levels, dtype=x.dtype, device=x.device)) * math.pi  # (L,)
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
    freqs = (2.0 ** torch.arange(levels, dtype=enc.dtype, device=enc.device)) * math.pi
    s = enc[:, d:d + d * levels].reshape(n, levels, d)
    c = enc[:, d + d * levels:].reshape(n, levels, d)
    u_s = u[:, d:d + d * levels].reshape(n, levels, d)
    u_c = u[:, d + d * levels:].reshape(n, levels, d)
    return u[:, :d] + ((c * u_s - s * u_c) * freqs[:, None]).sum(1)
