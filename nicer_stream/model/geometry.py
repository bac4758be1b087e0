"""Coarse + fine SDF (Sec. 3.1, Eqs. 1-3) with analytic spatial gradients."""
from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from nicer_stream.config import ModelConfig
from nicer_stream.model.dense_grid import DenseGrids, geometric_resolutions
from nicer_stream.model.mlp import GeometryMLP
from nicer_stream.model.positional import encoding_dim, positional_encoding
from nicer_stream.model.sdf_grad_assembly import assemble_sdf_grad


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

    def _sphere(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The initial sphere's SDF (N,) at normalised points x (N, 3), with x - centre (N, 3) and
        its norm r (N,) (the sphere's gradient is -(x - centre) / r)."""
        xc = x - self.sphere_centre
        r = xc.norm(dim=-1).clamp_min(1e-9)
        return self.sphere_radius - r, xc, r

    def sdf(self, x: torch.Tensor, use_fine: bool = True) -> torch.Tensor:
        """The SDF alone (N,) at normalised points x (N, 3): `forward(x).sdf` without computing
        the features (probes, meshing)."""
        pe = positional_encoding(x, self.cfg.pe_levels)
        gc, _ = self.coarse_grid(x)
        sdf = self._sphere(x)[0] + self.coarse_mlp(torch.cat([pe, gc], -1), 1)[:, 0]
        if use_fine:
            gf, _ = self.fine_grid(x)
            sdf = sdf + self.fine_mlp(torch.cat([pe, gf], -1), 1)[:, 0]
        return sdf

    def forward(self, x: torch.Tensor, use_fine: bool = True, with_grad: bool = False) -> GeometrySample:
        """x (N, 3) normalised coordinates.

        With `with_grad`, each MLP returns u = d s / d(its input) and the spatial gradient is
        J u, contracted part by part in one node (`sdf_grad_assembly.py`): the positional
        encoding's analytically, the grids' with their Jacobians; the sphere's term added."""
        pe = positional_encoding(x, self.cfg.pe_levels)
        gc, gc_j = self.coarse_grid(x, with_tangent=with_grad)
        h = torch.cat([pe, gc], dim=-1)
        out, u = self.coarse_mlp.value_and_input_grad(h) if with_grad else (self.coarse_mlp(h), None)
        sdf, xc, r = self._sphere(x)
        sdf = sdf + out[:, 0]
        z_coarse = out[:, 1:]
        z_fine = torch.zeros_like(z_coarse)
        parts = [(u, gc_j)]
        if use_fine:
            gf, gf_j = self.fine_grid(x, with_tangent=with_grad)
            hf = torch.cat([pe, gf], -1)
            fo, uf = self.fine_mlp.value_and_input_grad(hf) if with_grad else (self.fine_mlp(hf), None)
            sdf = sdf + fo[:, 0]
            parts.append((uf, gf_j))
            z_fine = fo[:, 1:]
        grad = None
        if with_grad:
            grad = assemble_sdf_grad(pe, self.cfg.pe_levels, parts) - xc / r[:, None]
        return GeometrySample(sdf, grad, z_coarse, z_fine)
