"""Where along each ray to evaluate the scene."""
from __future__ import annotations

import torch


def ray_box(origins: torch.Tensor, dirs: torch.Tensor, lo: float = -1.0, hi: float = 1.0):
    """Intersections of rays (normalised frame, (R,3) each) with the cube [lo, hi]^3 -> (t_near, t_far) (R,)."""
    inv = 1.0 / torch.where(dirs.abs() < 1e-9, torch.full_like(dirs, 1e-9), dirs)
    t0, t1 = (lo - origins) * inv, (hi - origins) * inv
    t_near = torch.minimum(t0, t1).amax(-1)
    t_far = torch.maximum(t0, t1).amin(-1)
    return t_near, t_far


def stratified(near: torch.Tensor, far: torch.Tensor, n: int, jitter: bool) -> torch.Tensor:
    """(R,) bounds -> (R, n) sorted samples, one per equal bin (random inside it if jitter)."""
    u = torch.arange(n, dtype=near.dtype, device=near.device)
    u = u + (torch.rand(near.shape[0], n, dtype=near.dtype, device=near.device) if jitter else 0.5)
    return near[:, None] + (far - near)[:, None] * (u / n)


def sample_pdf(bins: torch.Tensor, weights: torch.Tensor, n: int, jitter: bool) -> torch.Tensor:
    """Inverse-CDF sampling. bins (R, S+1) edges, weights (R, S) -> (R, n) samples."""
    w = weights + 1e-5
    pdf = w / w.sum(-1, keepdim=True)
    cdf = torch.cat([torch.zeros_like(pdf[:, :1]), torch.cumsum(pdf, -1)], -1)
    if jitter:
        u = torch.rand(cdf.shape[0], n, dtype=cdf.dtype, device=cdf.device)
    else:
        u = torch.linspace(0.5 / n, 1 - 0.5 / n, n, dtype=cdf.dtype, device=cdf.device).expand(cdf.shape[0], n)
    idx = torch.searchsorted(cdf.contiguous(), u.contiguous(), right=True).clamp(1, cdf.shape[-1] - 1)
    c0, c1 = cdf.gather(1, idx - 1), cdf.gather(1, idx)
    b0, b1 = bins.gather(1, idx - 1), bins.gather(1, idx)
    frac = (u - c0) / (c1 - c0).clamp_min(1e-9)
    return b0 + frac * (b1 - b0)
