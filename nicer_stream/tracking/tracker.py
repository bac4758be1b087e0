"""Camera tracking (Sec. 3.3): optimise one frame's pose against the frozen scene
with the RGB L1 loss on pixels redrawn every iteration; keep the best (or last) pose."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import torch

from nicer_stream.config import RenderConfig, TrackingConfig
from nicer_stream.errors import UserError
from nicer_stream.geometry.se3 import se3_exp
from nicer_stream.losses import rgb_l1
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mapping.ray_sampling import sample_pixels
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from nicer_stream.render.renderer import render_rays, rays_for_pixels


@dataclass
class TrackingResult:
    """T_world_cam (4, 4) chosen by `TrackingConfig.keep` (the lowest-loss iteration's, or
    the final iterate), the lowest loss seen (the failure checks compare it), the first loss,
    iterations, seconds."""

    T_world_cam: torch.Tensor
    loss: float
    initial_loss: float
    iters: int
    seconds: float


class Tracker:
    """Reads the scene (never writes it): gradients flow to the pose twist only."""

    def __init__(self, model: SceneModel, beta: BetaField, cfg: TrackingConfig, render: RenderConfig, seed: int = 0) -> None:
        if cfg.keep not in ("best", "last"):
            raise UserError(f"tracking.keep must be 'best' or 'last', got {cfg.keep!r}")
        self.model, self.beta, self.cfg = model, beta, cfg
        # Tracking may use fewer samples: the surface is already known.
        self.render = replace(render, **{k: getattr(cfg, k) for k in ("n_probe", "n_importance", "n_uniform")
                                         if getattr(cfg, k) is not None})
        self.gen = torch.Generator().manual_seed(seed)

    @torch.no_grad()
    def _observed(self, rays, out) -> torch.Tensor | None:
        """(R,) bool: the ray's rendered surface point lies in mapped space (`min_count`)."""
        if self.cfg.min_count <= 0:
            return None
        x = self.model.bound.normalise(rays.origins + rays.dirs * out.ray_dist[:, None])
        ok = self.beta.counts[self.beta.voxel_index(x)] > self.cfg.min_count
        return ok if ok.any() else None

    def track(self, frame: MapFrame, T_init: torch.Tensor) -> TrackingResult:
        with self.model.frozen():
            return self._track(frame, T_init)

    def _track(self, frame: MapFrame, T_init: torch.Tensor) -> TrackingResult:
        t0 = time.perf_counter()
        xi = torch.zeros(6, device=T_init.device, requires_grad=True)
        opt = torch.optim.Adam([xi], lr=self.cfg.lr)
        best_loss, best_xi, first = math.inf, torch.zeros(6, device=T_init.device), None
        # iters steps, each loss measured before its step, plus the loss of the final iterate.
        for it in range(self.cfg.iters + 1):
            T = T_init @ se3_exp(xi)
            uv, pix = sample_pixels(frame, self.cfg.rays, self.gen)
            rays = rays_for_pixels(uv, frame.intr, T)
            out = render_rays(self.model, self.beta, rays, self.render)
            loss = rgb_l1(out.rgb, frame.rgb.reshape(-1, 3)[pix], self._observed(rays, out))
            val = float(loss.detach())
            first = val if first is None else first
            if val < best_loss and math.isfinite(val):
                best_loss, best_xi = val, xi.detach().clone()
            if it == self.cfg.iters:
                break
            (grad,) = torch.autograd.grad(loss, [xi])
            if not torch.isfinite(grad).all():
                break
            xi.grad = grad
            opt.step()
        if self.cfg.keep == "last" and torch.isfinite(xi).all():
            best_xi = xi.detach()
        with torch.no_grad():
            T_best = T_init @ se3_exp(best_xi)
        return TrackingResult(T_best, best_loss, first if first is not None else math.nan, self.cfg.iters,
                              time.perf_counter() - t0)
