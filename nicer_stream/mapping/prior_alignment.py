"""Metric alignment of a relative depth prior from optical flow and known poses.

With known poses, flow correspondences triangulate a sparse metric depth; a robust
affine fit `prior = w * depth + q` then turns the whole prior into metres. This is
how `nicer-stream map` fixes the prior's scale and shift (the SLAM loop instead
fixes them in its first mapping, Sec. 3.4).
"""
from __future__ import annotations

import torch

from nicer_stream.geometry.camera import camera_dirs, pixel_grid
from nicer_stream.geometry.se3 import invert
from nicer_stream.render.renderer import render_rays, rays_for_pixels
from nicer_stream.types import Intrinsics


def triangulate_depth(uv: torch.Tensor, uv_dst: torch.Tensor, intr: Intrinsics, intr_dst: Intrinsics,
                      T_world_src: torch.Tensor, T_world_dst: torch.Tensor, min_parallax_px: float = 1.0):
    """z-depth in the source camera of pixels uv (N, 2) seen at uv_dst (N, 2) in the destination.

    Least squares along the source ray of the two reprojection equations. Returns
    (z (N,), ok (N,) bool: positive depth and at least `min_parallax_px` of parallax).
    """
    T = invert(T_world_dst) @ T_world_src  # T_dst_src
    a = camera_dirs(uv, intr).to(T.dtype) @ T[:3, :3].T  # direction of the source ray in dst frame (z=1 in src)
    b = T[:3, 3].expand_as(a)
    p = (uv_dst[:, 0] - intr_dst.cx) / intr_dst.fx
    q = (uv_dst[:, 1] - intr_dst.cy) / intr_dst.fy
    A = torch.stack([a[:, 0] - p * a[:, 2], a[:, 1] - q * a[:, 2]], -1)  # z * A = B
    B = torch.stack([p * b[:, 2] - b[:, 0], q * b[:, 2] - b[:, 1]], -1)
    z = (A * B).sum(-1) / (A * A).sum(-1).clamp_min(1e-12)
    # Parallax: how far the point moves on the destination image between depth z and infinity.
    inf_uv = torch.stack([a[:, 0] / a[:, 2], a[:, 1] / a[:, 2]], -1)
    dst_uv = torch.stack([p, q], -1)
    parallax = ((dst_uv - inf_uv) * torch.tensor([intr_dst.fx, intr_dst.fy], dtype=T.dtype)).norm(dim=-1)
    ok = (z > 0) & (parallax >= min_parallax_px) & torch.isfinite(z)
    return z, ok


def robust_affine_fit(prior: torch.Tensor, depth: torch.Tensor, iters: int = 3, keep: float = 0.8):
    """(w, q) with prior ~= w * depth + q by least squares, refitted `iters` times on the
    `keep` fraction of smallest residuals. Returns None with fewer than 20 points."""
    if prior.numel() < 20:
        return None
    sel = torch.ones_like(prior, dtype=torch.bool)
    w = q = None
    for _ in range(iters):
        x, y = depth[sel].double(), prior[sel].double()
        xm, ym = x.mean(), y.mean()
        var = ((x - xm) ** 2).mean()
        if var <= 1e-12:
            return None
        w = float(((x - xm) * (y - ym)).mean() / var)
        q = float(ym - w * xm)
        res = (prior - (w * depth + q)).abs()
        sel = res <= torch.quantile(res, keep)
    return w, q


def align_frame_prior(frame, partner, T_world_src: torch.Tensor, T_world_dst: torch.Tensor):
    """(w, q) of `frame.depth_prior` (a MapFrame) from its flow to `partner` and both poses, or None."""
    if frame.depth_prior is None or partner.index not in frame.flows:
        return None
    flow, valid = frame.flows[partner.index]
    uv = pixel_grid(frame.intr, device=flow.device).double()
    z, ok = triangulate_depth(uv, uv + flow.reshape(-1, 2).double(), frame.intr, partner.intr,
                              T_world_src.double(), T_world_dst.double())
    prior = frame.depth_prior.reshape(-1).double()
    ok &= valid.reshape(-1) & (prior > 0) & torch.isfinite(prior)
    return robust_affine_fit(prior[ok], z[ok])


def align_to_widest_partner(frame, frames: dict, poses: dict):
    """(w, q) of `frame` (a MapFrame) by `align_frame_prior` against the frame of `frames`
    (index -> MapFrame) it has a flow to whose centre is farthest from its own, under
    `poses` (index -> T_world_cam); None without a partner or a fit."""
    partners = [j for j in frame.flows if j in frames]
    if not partners:
        return None
    far = max(partners, key=lambda j: float((poses[j][:3, 3] - poses[frame.index][:3, 3]).norm()))
    return align_frame_prior(frame, frames[far], poses[frame.index], poses[far])


@torch.no_grad()
def align_prior_to_map(frame, T_world_cam: torch.Tensor, model, beta, render_cfg, step: int = 4):
    """(w, q) of `frame.depth_prior` (a MapFrame) against the depth the current map renders
    at `T_world_cam` on every `step`-th pixel, or None. Fixing them once when a frame is
    first mapped keeps every frame at the map's scale (the per-iteration fit of Eq. 10
    lets scale and shift follow whatever the rendered depth does)."""
    if frame.depth_prior is None:
        return None
    h, w = frame.intr.height, frame.intr.width
    uv = pixel_grid(frame.intr, device=frame.rgb.device).reshape(h, w, 2)[::step, ::step].reshape(-1, 2)
    out = render_rays(model, beta, rays_for_pixels(uv, frame.intr, T_world_cam), render_cfg, jitter=False)
    prior = frame.depth_prior[uv[:, 1].long(), uv[:, 0].long()]
    ok = (prior > 0) & torch.isfinite(prior) & (out.opacity > 0.9) & (out.depth > 0)
    return robust_affine_fit(prior[ok], out.depth[ok])
