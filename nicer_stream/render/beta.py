"""Beta of the SDF->density transform: locally adaptive (Eq. 8), global learnable, or fixed."""
from __future__ import annotations

import torch
from torch import nn

from nicer_stream.config import RenderConfig


def adaptive_beta(count: torch.Tensor, c0: float, c1: float, c2: float) -> torch.Tensor:
    """Eq. 8: beta = c0 * exp(-c1 * T_p) + c2 for voxel sample counts T_p."""
    return c0 * torch.exp(-c1 * count) + c2


class BetaField(nn.Module):
    """Beta at points of the normalised cube.

    'adaptive': a `beta_voxels`^3 counter of mapping samples (a buffer, saved with
    the model) drives Eq. 8. 'global': one learnable beta. 'fixed': a constant.
    """

    def __init__(self, cfg: RenderConfig) -> None:
        super().__init__()
        self.cfg = cfg
        n = cfg.beta_voxels
        self.register_buffer("counts", torch.zeros(n * n * n, dtype=torch.float64))
        self.log_beta = nn.Parameter(torch.tensor(float(cfg.beta_fixed)).log(), requires_grad=cfg.beta_mode == "global")

    def voxel_ijk(self, x: torch.Tensor) -> torch.Tensor:
        """(..., 3) normalised points -> (..., 3) integer voxel coordinates of the counter."""
        return ((x.detach().clamp(-1, 1 - 1e-6) + 1) / 2 * self.cfg.beta_voxels).long()

    def voxel_index(self, x: torch.Tensor) -> torch.Tensor:
        """(..., 3) normalised points -> (...) flat counter index."""
        n = self.cfg.beta_voxels
        i = self.voxel_ijk(x)
        return (i[..., 0] * n + i[..., 1]) * n + i[..., 2]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """x (..., 3) normalised -> beta (...) (or a 0-d tensor for global/fixed)."""
        if self.cfg.beta_mode == "fixed":
            return x.new_tensor(self.cfg.beta_fixed)
        if self.cfg.beta_mode == "global":
            return self.log_beta.exp().to(x.dtype)
        c = self.counts[self.voxel_index(x)].to(x.dtype)
        return adaptive_beta(c, self.cfg.beta_c0, self.cfg.beta_c1, self.cfg.beta_c2)

    @torch.no_grad()
    def count(self, x: torch.Tensor) -> None:
        """Add mapping samples x (..., 3) to the voxel counter."""
        idx = self.voxel_index(x).reshape(-1)
        w = torch.full(idx.shape, self.cfg.beta_count_weight, dtype=self.counts.dtype, device=idx.device)
        self.counts.index_add_(0, idx, w)

    def voxel_betas(self) -> tuple[torch.Tensor, torch.Tensor]:
        """Counted voxels -> (centres (K, 3) normalised, beta (K,))."""
        n = self.cfg.beta_voxels
        idx = torch.nonzero(self.counts > 0)[:, 0]
        ijk = torch.stack([idx // (n * n), (idx // n) % n, idx % n], -1).to(torch.float32)
        centres = (ijk + 0.5) / n * 2 - 1
        return centres, adaptive_beta(self.counts[idx].float(), self.cfg.beta_c0, self.cfg.beta_c1, self.cfg.beta_c2)
