"""Coarse + fine SDF (Sec. 3.1, Eqs. 1-3) with analytic spatial gradients."""
from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from nicer_stream.config import ModelConfig
from nicer_stream.model.dense_grid import DenseGrids, geometric_resolutions
from nicer_stream.model.mlp import GeometryMLP
from nicer_stream.model.positional import encoding_dim, positional_encoding


@dataclass
class GeometrySample:
    """SDF at N normalised points.

    sdf (N,), grad (N, 3) d sdf / d x_norm or None, z_coarse / z_fine (N, F) features
    (z_fine zeros while the fine level is off).
    """

    sdf: torch.Tensor
    grad: torch.Tensor | None
    z_coarse: torch.Tensor
    z_fine: torch.Tensor


def initial_sphere(mode: str, camera: torch.Tensor, default_radius: float, camera_radius: float) -> tuple[torch.Tensor, float]:
    """Centre (3,) and radius of the initial sphere, normalised units, for `ModelConfig.sphere_centre`
    `mode` ('bound', 'camera' or 'auto'; SlamSystem checks it with the other config values) and
    the first camera's normalised position `camera` (3,)."""
    outside = float(camera.norm()) >= default_radius
    if mode == "camera" or (mode == "auto" and outside):
        return camera.clone(), camera_radius
    return torch.zeros_like(camera), default_radius


class GeometryField(nn.Module):
    """s = s_coarse + delta_s; s_coarse starts as the sphere `radius - |x - centre|` (inside
    positive, normalised units): by default the bound's centre and `cfg.sphere_radius`; the
    SLAM may centre it on the first camera (`initial_sphere`, `set_sphere`): the camera must
    start in free space."""

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        self.cfg = cfg
        # Buffers, so that a saved scene keeps its initialisation.
        self.register_buffer("sphere_centre", torch.zeros(3))
        self.register_buffer("sphere_radius", torch.tensor(float(cfg.sphere_radius)))
        pe = encoding_dim(cfg.pe_levels)
        self.coarse_grid = DenseGrids([cfg.coarse_res], cfg.coarse_dim)
        self.coarse_mlp = GeometryMLP(pe + cfg.coarse_dim, cfg.coarse_hidden, 1, 1 + cfg.geo_feature_dim)
        fine_res = geometric_resolutions(cfg.fine_res_min, cfg.fine_res_max, cfg.fine_levels)
        self.fine_grid = DenseGrids(fine_res, cfg.fine_dim)
        self.fine_mlp = GeometryMLP(pe + self.fine_grid.out_dim, cfg.fine_hidden, cfg.fine_layers, 1 + cfg.geo_feature_dim)

    def set_sphere(self, centre: torch.Tensor, radius: float) -> None:
        """Centre (3,) and radius of the initial sphere, normalised units."""
        self.sphere_centre.copy_(centre)
        self.sphere_radius.fill_(radius)

    def forward(self, x: torch.Tensor, use_fine: bool = True, with_grad: bool = False) -> GeometrySample:
        """x (N, 3) normalised coordinates."""
        tan = with_grad
        pe = positional_encoding(x, self.cfg.pe_levels, with_tangent=tan)
        pe, pe_j = (pe if tan else (pe, None))
        gc, gc_j = self.coarse_grid(x, with_tangent=tan)
        h = torch.cat([pe, gc], dim=-1)
        hj = torch.cat([pe_j, gc_j], dim=-1) if tan else None
        out, out_g = self.coarse_mlp.value_and_grad0(h, hj) if tan else (self.coarse_mlp(h), None)
        xc = x - self.sphere_centre
        r = xc.norm(dim=-1).clamp_min(1e-9)
        sdf = self.sphere_radius - r + out[:, 0]
        grad = (-xc / r[:, None] + out_g) if tan else None
        z_coarse = out[:, 1:]
        z_fine = torch.zeros_like(z_coarse)
        if use_fine:
            gf, gf_j = self.fine_grid(x, with_tangent=tan)
            hf = torch.cat([pe, gf], -1)
            fo, fo_g = self.fine_mlp.value_and_grad0(hf, torch.cat([pe_j, gf_j], -1)) if tan else (self.fine_mlp(hf), None)
            sdf = sdf + fo[:, 0]
            if tan:
                grad = grad + fo_g
            z_fine = fo[:, 1:]
        return GeometrySample(sdf, grad, z_coarse, z_fine)
