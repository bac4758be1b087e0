"""Multi-resolution hash grid (Instant-NGP style) over [-1, 1]^3, pure torch.

Levels whose dense vertex count fits the table are indexed densely; finer
levels use the spatial hash of Mueller et al. 2022. Used for colour, so no
spatial Jacobian is needed.
"""
from __future__ import annotations

import torch
from torch import nn

from nicer_stream.model.dense_grid import cell_coords, corner_weights, geometric_resolutions
from nicer_stream.model.gather import gather_rows
from nicer_stream.model.grid_kernel import GridSpec, grid_interp, kernel_available

_PRIMES = (1, 2654435761, 805459861)


class HashGrids(nn.Module):
    """`levels` grids of `dim` features, resolutions geometric in [r_min, r_max], 2^log2_size rows each."""

    def __init__(self, levels: int, dim: int, r_min: int, r_max: int, log2_size: int, init_std: float = 1e-4) -> None:
        super().__init__()
        self.resolutions = geometric_resolutions(r_min, r_max, levels)
        self.dim = dim
        self.size = 2**log2_size
        self.register_buffer("res", torch.tensor(self.resolutions, dtype=torch.long), persistent=False)
        self.register_buffer("dense", torch.tensor([r**3 <= self.size for r in self.resolutions]), persistent=False)
        self.register_buffer("level_offset", torch.arange(levels) * self.size, persistent=False)
        self.table = nn.Parameter((torch.rand(levels * self.size, dim) * 2 - 1) * init_std)
        self.spec = GridSpec(self.resolutions, [l * self.size for l in range(levels)], [self.size] * levels,
                             (~self.dense).tolist())

    @property
    def out_dim(self) -> int:
        return len(self.resolutions) * self.dim

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """x (N, 3) in [-1, 1] -> (N, levels*dim): the compiled kernel where available."""
        if kernel_available(self.table):
            return grid_interp(self.table, x.to(self.table.dtype), self.spec, False)[0]
        return self.reference_forward(x)

    def reference_forward(self, x: torch.Tensor) -> torch.Tensor:
        """Pure-torch hashed trilinear gather."""
        n = x.shape[0]
        i0, frac, _ = cell_coords(x, self.res)
        c = torch.stack([i0, i0 + 1], dim=-1)  # (N, L, 3, 2) per-axis corner coordinates
        cx, cy, cz = c[..., 0, :, None, None], c[..., 1, None, :, None], c[..., 2, None, None, :]
        r = self.res[None, :, None, None, None]
        dense_idx = ((cx * r + cy) * r + cz).flatten(-3)
        hashed = ((cx * _PRIMES[0]) ^ (cy * _PRIMES[1]) ^ (cz * _PRIMES[2])).flatten(-3) % self.size
        idx = torch.where(self.dense[None, :, None], dense_idx, hashed) + self.level_offset[None, :, None]
        feats = gather_rows(self.table, idx)  # (N, L, 8, C)
        w, _ = corner_weights(frac, with_tangent=False)
        return torch.einsum("nlk,nlkc->nlc", w, feats).reshape(n, -1)
