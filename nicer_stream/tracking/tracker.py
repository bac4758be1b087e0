"""Camera tracking (Sec. 3.3): optimise one frame's pose against the frozen scene
with the RGB loss on pixels redrawn every iteration; keep the best (or last) pose.

Two optimisers: 'adam' on the L1 loss (the paper), and 'gauss_newton' (Levenberg-Marquardt
with Huber weights, `tracking/gauss_newton.py`), which takes a handful of iterations and
stops when the step is below `stop_m` / `stop_rad`.

With `affine_brightness` the frame's gain and bias are fitted in closed form to each
iteration's render before the residual is taken (`losses/brightness.py`): for a fixed render
the best affine map is exact, so the pose's gradient is that of the loss minimised over it."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import torch

from nicer_stream.config import RenderConfig, TrackingConfig
from nicer_stream.denormals import flush_denormals
from nicer_stream.geometry.se3 import invert, se3_exp, se3_log
from nicer_stream.losses import rgb_l1
from nicer_stream.losses.brightness import apply_brightness, fit_brightness
from nicer_stream.losses.robust import huber_weights
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mapping.ray_sampling import sample_pixels
from nicer_stream.tracking.gauss_newton import damped_step, ray_twist_jacobian
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from nicer_stream.render.renderer import RayBatch, render_rays, rays_for_pixels


@dataclass
class TrackingResult:
    """T_world_cam (4, 4) chosen by `TrackingConfig.keep` (the lowest-loss iteration's, or
    the final iterate), the lowest loss seen (the failure checks compare it), the first loss,
    iterations, seconds; with `affine_brightness`, the frame's (a, b) fitted at the last iteration."""

    T_world_cam: torch.Tensor
    loss: float
    initial_loss: float
    iters: int
    seconds: float
    brightness: tuple[float, float] | None = None


def decayed_lr(lr: float, decay: float, step: int, steps: int) -> float:
    """Learning rate of step `step` of `steps` (0-based), geometric from `lr` at the first to
    `lr * decay` at the last (`decay` 1: constant)."""
    return lr * decay ** (step / max(steps - 1, 1))


class Tracker:
    """Reads the scene (never writes it): gradients flow to the pose twist only."""

    def __init__(self, model: SceneModel, beta: BetaField, cfg: TrackingConfig, render: RenderConfig, seed: int = 0) -> None:
        self.model, self.beta, self.cfg = model, beta, cfg
        # Tracking may use fewer samples: the surface is already known.
        # Its own transmittance cut, and no band behind surfaces: tracking has no Eikonal term.
        self.render = replace(render, min_transmittance=cfg.min_transmittance, keep_band_m=0.0,
                              **{k: getattr(cfg, k) for k in ("n_probe", "n_importance", "n_uniform")
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

    def _brightness(self, rendered: torch.Tensor, observed: torch.Tensor, mask: torch.Tensor | None) -> torch.Tensor | None:
        """(2,) (a, b) mapping this iteration's (N, 3) render onto the frame's colours on the
        pixels that count (None without `affine_brightness`)."""
        if not self.cfg.affine_brightness:
            return None
        huber = self.cfg.huber_delta if (self.cfg.huber or self.cfg.optimizer == "gauss_newton") else 0.0
        return fit_brightness(rendered, observed, None if mask is None else mask.to(rendered.dtype),
                              self.cfg.brightness_prior, huber, max_gain=self.cfg.max_gain)

    @flush_denormals()
    def track(self, frame: MapFrame, T_init: torch.Tensor) -> TrackingResult:
        with self.model.frozen():
            if self.cfg.optimizer == "gauss_newton":
                return self._track_gauss_newton(frame, T_init)
            return self._track_adam(frame, T_init)

    def _track_gauss_newton(self, frame: MapFrame, T_init: torch.Tensor) -> TrackingResult:
        """Levenberg-Marquardt on the colour residuals of fresh pixels each iteration; the
        reported losses are the L1 loss of the Adam path, on the same pixels."""
        t0 = time.perf_counter()
        cfg = self.cfg
        T, losses, it, iterates = T_init.detach().clone(), [], 0, []
        target = frame.rgb.reshape(-1, 3)
        while True:
            uv, pix = sample_pixels(frame, cfg.rays, self.gen)
            base = rays_for_pixels(uv, frame.intr, T)
            o = base.origins.detach().requires_grad_(True)
            d = base.dirs.detach().requires_grad_(True)
            rays = RayBatch(o, d, base.z_per_dist)
            out = render_rays(self.model, self.beta, rays, self.render)
            mask = self._observed(rays, out)
            ab = self._brightness(out.rgb, target[pix], mask)
            pred = out.rgb if ab is None else apply_brightness(out.rgb, ab)
            res = pred - target[pix]
            losses.append(float(rgb_l1(pred.detach(), target[pix], mask, cfg.huber_delta if cfg.huber else 0.0)))
            if it == cfg.iters or not math.isfinite(losses[-1]):
                break
            # One residual per channel (three backward passes), or the grey level's (one).
            values = out.rgb.mean(-1, keepdim=True) if cfg.residual == "grey" else out.rgb
            r = (res.mean(-1, keepdim=True) if cfg.residual == "grey" else res).detach().T  # (C, N)
            g = [torch.autograd.grad(values[:, c].sum(), [o, d], retain_graph=c < len(r) - 1) for c in range(len(r))]
            g_o, g_d = torch.stack([a for a, _ in g]), torch.stack([b for _, b in g])  # (C, N, 3)
            J = ray_twist_jacobian(g_o, g_d, d.detach(), T[:3, :3])  # (C, N, 6)
            if ab is not None:  # the residual sees the render through the gain
                J = J * torch.exp(ab[0])
            keep = mask if mask is not None else torch.ones_like(r[0], dtype=torch.bool)
            J, r = J[:, keep].reshape(-1, 6), r[:, keep].reshape(-1)
            step = damped_step(J, r, huber_weights(r, cfg.huber_delta), cfg.damping)
            if not torch.isfinite(step).all():
                break
            # A step larger than the bound is shortened: a linearisation holds only nearby.
            scale = min(1.0, cfg.max_step_m / max(float(step[:3].norm()), 1e-12),
                        cfg.max_step_rad / max(float(step[3:].norm()), 1e-12))
            T = T @ se3_exp(step * scale)
            iterates.append(T)
            it += 1
            if float(step[:3].norm()) < cfg.stop_m and float(step[3:].norm()) < cfg.stop_rad:
                losses.append(losses[-1])  # converged: the last step changed (almost) nothing
                break
        ok = [v for v in losses if math.isfinite(v)]
        if cfg.average > 1 and len(iterates) > 1:
            # Near the optimum each step re-fits fresh pixels: iterates scatter around it by the
            # sampling noise; their mean (in the tangent space of the last) scatters less.
            last = iterates[-cfg.average:]
            xi = torch.stack([se3_log(invert(T) @ Ti) for Ti in last]).mean(0)
            T = T @ se3_exp(xi)
        return TrackingResult(T, min(ok) if ok else math.nan, losses[0], it, time.perf_counter() - t0,
                              None if ab is None else (float(ab[0]), float(ab[1])))

    def _track_adam(self, frame: MapFrame, T_init: torch.Tensor) -> TrackingResult:
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
            target, mask = frame.rgb.reshape(-1, 3)[pix], self._observed(rays, out)
            ab = self._brightness(out.rgb, target, mask)
            pred = out.rgb if ab is None else apply_brightness(out.rgb, ab)
            loss = rgb_l1(pred, target, mask, self.cfg.huber_delta if self.cfg.huber else 0.0)
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
            # Near the optimum Adam's steps stay ~lr long, each fitting fresh pixels: the final pose
            # scatters with the pixel draw unless the rate falls (`lr_decay`).
            opt.param_groups[0]["lr"] = decayed_lr(self.cfg.lr, self.cfg.lr_decay, it, self.cfg.iters)
            opt.step()
        if self.cfg.keep == "last" and torch.isfinite(xi).all():
            best_xi = xi.detach()
        with torch.no_grad():
            T_best = T_init @ se3_exp(best_xi)
        return TrackingResult(T_best, best_loss, first if first is not None else math.nan, self.cfg.iters,
                              time.perf_counter() - t0, None if ab is None else (float(ab[0]), float(ab[1])))
