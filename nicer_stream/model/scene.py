"""The scene model: geometry + colour inside a SceneBound, with optimiser parameter groups."""
from __future__ import annotations

from contextlib import contextmanager

import torch
from torch import nn

from nicer_stream.config import MappingConfig, ModelConfig
from nicer_stream.model.bound import SceneBound
from nicer_stream.model.color import ColorField
from nicer_stream.model.geometry import GeometryField


class SceneModel(nn.Module):
    """Owns all scene parameters. Inputs are world metres; the bound normalises them."""

    def __init__(self, cfg: ModelConfig, bound: SceneBound) -> None:
        super().__init__()
        self.cfg = cfg
        self.bound = bound
        self.geometry = GeometryField(cfg)
        self.color = ColorField(cfg)

    def param_groups(self, m: MappingConfig) -> dict[str, dict]:
        """Named Adam groups with the release's learning-rate factors."""
        g = self.geometry
        return {
            "coarse": {"params": [g.coarse_grid.table], "lr": m.lr * m.lr_geo_grid_factor},
            "coarse_mlp": {"params": list(g.coarse_mlp.parameters()), "lr": m.lr},
            "fine": {"params": [g.fine_grid.table], "lr": m.lr * m.lr_geo_grid_factor},
            "fine_mlp": {"params": list(g.fine_mlp.parameters()), "lr": m.lr},
            "color_grid": {"params": [self.color.grid.table], "lr": m.lr * m.lr_color_grid_factor},
            "color_mlp": {"params": list(self.color.mlp.parameters()), "lr": m.lr},
        }

    def grid_tables(self) -> list[torch.Tensor]:
        """The feature-grid tables (coarse, fine, colour): nearly all of the parameters."""
        return [self.geometry.coarse_grid.table, self.geometry.fine_grid.table, self.color.grid.table]

    @contextmanager
    def frozen(self):
        """No parameter requires grad inside: a pose-only backward (tracking) then skips every
        parameter gradient, which `autograd.grad(loss, [pose])` alone would not (custom nodes
        on the path to the pose compute all of their inputs' gradients)."""
        saved = [(p, p.requires_grad) for p in self.parameters()]
        for p, _ in saved:
            p.requires_grad_(False)
        try:
            yield self
        finally:
            for p, flag in saved:
                p.requires_grad_(flag)

    def parameters_changed(self) -> None:
        """Call after every optimiser step: drops caches derived from the parameters."""
        self.geometry.coarse_grid.invalidate()
        self.geometry.fine_grid.invalidate()

    @torch.no_grad()
    def sdf_world(self, x_world: torch.Tensor, use_fine: bool = True) -> torch.Tensor:
        """(N, 3) world -> (N,) SDF in metres."""
        return self.geometry.sdf(self.bound.normalise(x_world), use_fine=use_fine) * self.bound.half_extent

    @torch.no_grad()
    def color_world(self, x_world: torch.Tensor, normal: torch.Tensor, use_fine: bool = True) -> torch.Tensor:
        """(N, 3) world points and normals -> (N, 3) RGB; view direction taken as -normal."""
        x = self.bound.normalise(x_world)
        g = self.geometry(x, use_fine=use_fine)
        return self.color(x, normal, -normal, g.z_coarse, g.z_fine)
