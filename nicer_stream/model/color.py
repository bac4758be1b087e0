"""Colour field (Sec. 3.1): hash grid + MLP fed with x, normal, gamma(view), z_coarse, z_fine."""
from __future__ import annotations

import torch
from torch import nn

from nicer_stream.config import ModelConfig
from nicer_stream.model.hash_grid import HashGrids
from nicer_stream.model.mlp import plain_mlp
from nicer_stream.model.positional import encoding_dim, positional_encoding


class ColorField(nn.Module):
    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        self.cfg = cfg
        self.grid = HashGrids(cfg.color_levels, cfg.color_dim, cfg.color_res_min, cfg.color_res_max, cfg.color_log2_table)
        in_dim = 3 + 3 + encoding_dim(cfg.view_pe_levels) + 2 * cfg.geo_feature_dim + self.grid.out_dim
        self.mlp = plain_mlp(in_dim, cfg.color_hidden, cfg.color_layers, 3)

    def forward(self, x, normal, view_dir, z_coarse, z_fine) -> torch.Tensor:
        """All (N, .) in the normalised/world-aligned frame -> (N, 3) RGB in [0, 1]."""
        h = torch.cat(
            [x, normal, positional_encoding(view_dir, self.cfg.view_pe_levels), z_coarse, z_fine, self.grid(x)], dim=-1
        )
        return torch.sigmoid(self.mlp(h))
