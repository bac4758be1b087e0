"""Multi-resolution dense feature grids over [-1, 1]^3 with trilinear interpolation.

Interpolation returns the features and, optionally, their analytic spatial
Jacobian so that SDF normals need no double backward. Index and weight
tensors are built per axis and combined by broadcasting: (N, L, 2, 2, 2)
rather than materialising (N, L, 8, 3) integer corners (memory-bound on CPU).
"""
from __future__ import annotations

import math

import torch
from torch import nn

from nicer_stream.model.gather import gather_rows


def geometric_resolutions(r_min: int, r_max: int, levels: int) -> list[int]:
    """Paper Eq. 2: R_l = floor(R_min * b^l), b = exp((ln R_max - ln R_min) / (L - 1))."""
    if levels == 1:
        return [r_min]
    b = math.exp((math.log(r_max) - math.log(r_min)) / (levels - 1))
    return [int(math.floor(r_min * b**l + 1e-6)) for l in range(levels)]


def cell_coords(x: torch.Tensor, res: torch.Tensor):
    """x (N, 3) in [-1, 1], res (L,) vertices per axis -> (i0 (N, L, 3) long, frac (N, L, 3), du/dx (L,))."""
    scale = (res.to(x.dtype) - 1) / 2
    u = (x.clamp(-1, 1)[:, None, :] + 1) * scale[None, :, None]
    i0 = torch.minimum(u.detach().floor().long().clamp_(min=0), (res - 2)[None, :, None])
    return i0, u - i0.to(x.dtype), scale


def corner_weights(frac: torch.Tensor, with_tangent: bool):
    """frac (N, L, 3) -> w (N, L, 8) and optionally dw/dfrac (N, L, 3, 8).

    Corner c = 4*bx + 2*by + bz, weight prod_axis (frac if bit else 1 - frac).
    """
    a = torch.stack([1 - frac, frac], dim=-1)  # (N, L, 3, 2)
    ax, ay, az = a[..., 0, :], a[..., 1, :], a[..., 2, :]
    w = (ax[..., :, None, None] * ay[..., None, :, None] * az[..., None, None, :]).flatten(-3)
    if not with_tangent:
        return w, None
    s = a.new_tensor([-1.0, 1.0]).expand_as(ax)
    dx = (s[..., :, None, None] * ay[..., None, :, None] * az[..., None, None, :]).flatten(-3)
    dy = (ax[..., :, None, None] * s[..., None, :, None] * az[..., None, None, :]).flatten(-3)
    dz = (ax[..., :, None, None] * ay[..., None, :, None] * s[..., None, None, :]).flatten(-3)
    return w, torch.stack([dx, dy, dz], dim=-2)


class DenseGrids(nn.Module):
    """L dense grids of `dim` features at vertex resolutions `resolutions`, stored in one table."""

    def __init__(self, resolutions: list[int], dim: int, init_std: float = 1e-4) -> None:
        super().__init__()
        self.resolutions = list(resolutions)
        self.dim = dim
        sizes = [r**3 for r in self.resolutions]
        offsets = [sum(sizes[:l]) for l in range(len(sizes))]
        self.register_buffer("offsets", torch.tensor(offsets, dtype=torch.long), persistent=False)
        self.register_buffer("res", torch.tensor(self.resolutions, dtype=torch.long), persistent=False)
        # Flat-index offset of each of the 8 cell corners, per level: (L, 8).
        corner = torch.tensor([[(c >> 2) & 1, (c >> 1) & 1, c & 1] for c in range(8)])
        r = self.res[:, None]
        self.register_buffer("corner_offsets", corner[None, :, 0] * r * r + corner[None, :, 1] * r + corner[None, :, 2], persistent=False)
        self.table = nn.Parameter(torch.randn(sum(sizes), dim) * init_std)

    @property
    def out_dim(self) -> int:
        return len(self.resolutions) * self.dim

    def forward(self, x: torch.Tensor, with_tangent: bool = False):
        """x (N, 3) in [-1, 1] -> features (N, L*dim) and optionally d/dx (N, 3, L*dim)."""
        n = x.shape[0]
        i0, frac, scale = cell_coords(x, self.res)
        r = self.res[None, :]
        base = (i0[..., 0] * r + i0[..., 1]) * r + i0[..., 2] + self.offsets[None, :]  # (N, L)
        feats = gather_rows(self.table, base[..., None] + self.corner_offsets[None])  # (N, L, 8, C)
        w, dw = corner_weights(frac, with_tangent)
        out = torch.einsum("nlk,nlkc->nlc", w, feats).reshape(n, -1)
        if not with_tangent:
            return out, None
        dw = dw * scale[None, :, None, None]  # chain rule du/dx
        jac = torch.einsum("nljk,nlkc->njlc", dw, feats).reshape(n, 3, -1)
        return out, jac
