"""Render rays through a SceneModel: probe without gradient, then importance
samples with gradient, VolSDF density with (locally adaptive) beta, Eqs. 5-6.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from nicer_stream.config import RenderConfig
from nicer_stream.denormals import flush_denormals
from nicer_stream.geometry.camera import pixel_grid, rays_world
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from nicer_stream.render.density import laplace_density
from nicer_stream.render.live_samples import interpolate_along_rays, kept_indices, live_mask
from nicer_stream.render.probe import SEGMENT, composite_deltas, probe_pass, probe_sdf
from nicer_stream.render.sampling import ray_box, sample_pdf, stratified
from nicer_stream.render.volume import accumulate, render_weights
from nicer_stream.types import Intrinsics


@dataclass
class RayBatch:
    """R rays in world coordinates: origins (R, 3), unit dirs (R, 3), z_per_dist (R,) (= d_z in camera frame)."""

    origins: torch.Tensor
    dirs: torch.Tensor
    z_per_dist: torch.Tensor


@dataclass
class RenderOutput:
    """Per ray: rgb (R, 3), depth (R,) z-depth m, ray_dist (R,) m, normal (R, 3) world
    (unnormalised weighted sum, Eq. 6), opacity (R,). Per sample (with gradient):
    points (R*S, 3) normalised, sdf_grad (N, 3) d sdf / d x_norm at the N samples that went
    through the network (all R*S, or those the light reaches with `min_transmittance` > 0; without
    autograd: those with non-negligible weight)."""

    rgb: torch.Tensor
    depth: torch.Tensor
    ray_dist: torch.Tensor
    normal: torch.Tensor
    opacity: torch.Tensor
    points: torch.Tensor
    sdf_grad: torch.Tensor


def render_rays(model: SceneModel, beta: BetaField, rays: RayBatch, cfg: RenderConfig,
                use_fine: bool = True, jitter: bool = True, depth_only: bool = False,
                probe_segment: int = SEGMENT) -> RenderOutput:
    """Differentiable rendering of `rays` (w.r.t. scene parameters and ray origins/dirs).

    `depth_only` (without autograd only): depth, ray distance and opacity as usual, while rgb
    and normal are left zero (no SDF gradients, no colour network: ~40% less work).
    `probe_segment`: probes per ray between two early-stop checks (`render/probe.py`)."""
    b = model.bound
    o = b.normalise(rays.origins)
    d = rays.dirs
    near, far = ray_box(o.detach(), d.detach())
    near = near.clamp_min(cfg.near_m / b.half_extent)
    far = torch.maximum(far, near + 1e-3)
    r = o.shape[0]
    with torch.no_grad():
        t_probe = stratified(near, far, cfg.n_probe, jitter)
        x_probe = o[:, None] + t_probe[..., None] * d[:, None]
        w_p, sdf_p = probe_pass(model, beta, x_probe, composite_deltas(t_probe, far), use_fine, cfg.probe_stop_tau,
                                probe_segment)
        mids = (t_probe[:, 1:] + t_probe[:, :-1]) / 2
        bins = torch.cat([near[:, None], mids, far[:, None]], -1)
        t_imp = sample_pdf(bins, w_p, cfg.n_importance, jitter)
        t_uni = stratified(near, far, cfg.n_uniform, jitter) if cfg.n_uniform > 0 else t_imp[:, :0]
        t, _ = torch.sort(torch.cat([t_imp, t_uni], -1), -1)
    x = (o[:, None] + t[..., None] * d[:, None]).reshape(-1, 3)
    s = t.shape[1]
    view = d[:, None].expand(r, s, 3).reshape(-1, 3)
    bx = beta(x)
    bx = bx.reshape(r, s) if bx.dim() else bx
    if torch.is_grad_enabled():
        # With `min_transmittance`, only the samples the light reaches go through the network
        # (`render/live_samples.py`); the others keep the probes' SDF estimate (no gradient), no
        # normal and no colour.
        kept = None
        if cfg.min_transmittance > 0:
            sdf_est = interpolate_along_rays(t_probe, sdf_p, t)  # no gradient: probes and t have none
            band = cfg.keep_band_m / b.half_extent
            kept = kept_indices(live_mask(sdf_est, bx, t, far, cfg.min_transmittance, band).reshape(-1))
        xs, vs = (x, view) if kept is None else (x[kept], view[kept])
        geo = model.geometry(xs, use_fine=use_fine, with_grad=True)
        normal = geo.grad / geo.grad.norm(dim=-1, keepdim=True).clamp_min(1e-6)
        rgb_s = model.color(xs, normal, vs, geo.z_coarse, geo.z_fine)
        sdf = geo.sdf
        if kept is not None:
            sdf = sdf_est.reshape(-1).index_put((kept,), sdf)
            normal = x.new_zeros(r * s, 3).index_put((kept,), normal)
            rgb_s = x.new_zeros(r * s, 3).index_put((kept,), rgb_s)
        w = render_weights(laplace_density(sdf.reshape(r, s), bx), composite_deltas(t, far))
        sdf_grad = geo.grad
    else:
        # Inference: weights from the SDF alone, then normals and colour only at the
        # samples that can matter (a few per ray).
        sdf = probe_sdf(model, x, use_fine)
        w = render_weights(laplace_density(sdf.reshape(r, s), bx), composite_deltas(t, far))
        normal, rgb_s = x.new_zeros(x.shape[0], 3), x.new_zeros(x.shape[0], 3)
        sdf_grad = x.new_zeros(0, 3)
        keep = (w.reshape(-1) > 1e-4).nonzero()[:, 0]
        if not depth_only and len(keep):
            geo = model.geometry(x[keep], use_fine=use_fine, with_grad=True)
            normal[keep] = geo.grad / geo.grad.norm(dim=-1, keepdim=True).clamp_min(1e-6)
            rgb_s[keep] = model.color(x[keep], normal[keep], view[keep], geo.z_coarse, geo.z_fine)
            sdf_grad = geo.grad
    ray_dist = accumulate(w, t) * b.half_extent
    return RenderOutput(
        rgb=accumulate(w, rgb_s.reshape(r, s, 3)),
        depth=ray_dist * rays.z_per_dist,
        ray_dist=ray_dist,
        normal=accumulate(w, normal.reshape(r, s, 3)),
        opacity=w.sum(-1),
        points=x,
        sdf_grad=sdf_grad,
    )


def rays_for_pixels(uv: torch.Tensor, intr: Intrinsics, T_world_cam: torch.Tensor) -> RayBatch:
    """RayBatch through pixels uv (R, 2) of a camera at T_world_cam (4, 4)."""
    o, d, zpd = rays_world(uv, intr, T_world_cam)
    return RayBatch(o, d, zpd)


@torch.no_grad()
def depth_at_pixels(model: SceneModel, beta: BetaField, cfg: RenderConfig, T_world_cam: np.ndarray,
                    intr: Intrinsics, uv: np.ndarray, min_opacity: float, min_samples: float = 0.0) -> np.ndarray:
    """The map's z-depth (N,) float64 at pixels `uv` (N, 2) of a camera at T_world_cam (4, 4);
    nan where the ray is less than `min_opacity` opaque or its surface lies in a voxel that mapping
    sampled fewer than `min_samples` times (`BetaField.counts`): places the map has not seen."""
    dev = next(model.parameters()).device
    T = torch.as_tensor(T_world_cam, dtype=torch.float32, device=dev)
    uv_t = torch.as_tensor(uv, dtype=torch.float32, device=dev)
    z = []
    for i in range(0, len(uv), cfg.chunk_rays):
        rays = rays_for_pixels(uv_t[i:i + cfg.chunk_rays], intr, T)
        out = render_rays(model, beta, rays, cfg, jitter=False, depth_only=True)
        surface = model.bound.normalise(rays.origins + rays.dirs * out.ray_dist[:, None])
        seen = beta.counts[beta.voxel_index(surface)] >= min_samples * beta.cfg.beta_count_weight
        z.append(torch.where((out.opacity >= min_opacity) & seen, out.depth, torch.nan))
    return torch.cat(z).double().cpu().numpy() if z else np.zeros(0)


@dataclass
class RenderedImage:
    """A whole view: rgb (H, W, 3) [0,1], depth (H, W) z-depth m, normal (H, W, 3) camera frame, opacity (H, W)."""

    rgb: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    opacity: np.ndarray


# Whole images stop their probes every 8 (of `fast`'s 32): with 2048-ray chunks the smaller passes
# cost less than the probes behind the first surface they skip (the demo's map at 320x240, one
# run: 4.6 -> 3.8-4.0 s; depth within 4e-6 m). The batches of tracking and mapping keep one pass.
IMAGE_PROBE_SEGMENT = 8


@torch.no_grad()
@flush_denormals()
def render_image(model: SceneModel, beta: BetaField, T_world_cam: torch.Tensor, intr: Intrinsics,
                 cfg: RenderConfig, use_fine: bool = True, depth_only: bool = False) -> RenderedImage:
    """Render a full view without autograd, in chunks (gradients are never needed here);
    `depth_only` leaves rgb and normal zero (see `render_rays`)."""
    dev = T_world_cam.device
    uv = pixel_grid(intr, device=dev)
    outs = []
    for i in range(0, uv.shape[0], cfg.chunk_rays):
        rays = rays_for_pixels(uv[i:i + cfg.chunk_rays], intr, T_world_cam)
        out = render_rays(model, beta, rays, cfg, use_fine=use_fine, jitter=False, depth_only=depth_only,
                          probe_segment=IMAGE_PROBE_SEGMENT)
        outs.append(torch.cat([out.rgb, out.depth[:, None], out.normal, out.opacity[:, None]], -1).detach())
    img = torch.cat(outs).reshape(intr.height, intr.width, 8)
    R = T_world_cam[:3, :3]
    n_cam = img[..., 4:7] @ R  # world -> camera: R^T n, row-vector form
    return RenderedImage(
        rgb=img[..., :3].clamp(0, 1).cpu().numpy(),
        depth=img[..., 3].cpu().numpy(),
        normal=n_cam.cpu().numpy(),
        opacity=img[..., 7].cpu().numpy(),
    )
