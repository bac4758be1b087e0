"""Initial pose of a new frame from the flow prior and the map (tracking init 'flow').

Pixels of stored frames (keyframes) with a flow to the new frame are lifted to 3D with
the depth the map renders at their estimated poses; the flow puts them on the new image,
and PnP with RANSAC gives the pose. The result sits at the map's own scale, which the
photometric tracker then only refines: started from the previous pose, a few dozen RGB
iterations recover only part of a frame's motion, and the deficit accumulates into a
trajectory shorter than the map (Replica clip: translations ~10% short).
"""
from __future__ import annotations

import numpy as np
import torch

from nicer_stream.config import RenderConfig
from nicer_stream.geometry.pose_estimation import pnp_pose
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.render.renderer import render_rays, rays_for_pixels


@torch.no_grad()
def flow_points(src: MapFrame, T_world_src: torch.Tensor, dst_index: int, model, beta, render: RenderConfig,
                n: int, gen: torch.Generator, min_opacity: float = 0.95):
    """Up to `n` correspondences from `src`'s flow to frame `dst_index`: (world points (M, 3),
    destination pixels (M, 2)) as float64 numpy, world points from the rendered z-depth of
    pixels whose flow is valid and whose ray is opaque; None without a flow."""
    if dst_index not in src.flows:
        return None
    flow, valid = src.flows[dst_index]
    ids = valid.reshape(-1).nonzero()[:, 0]
    if len(ids) == 0:
        return None
    ids = ids[torch.randperm(len(ids), generator=gen)[:n].to(ids.device)]
    w = src.intr.width
    uv = torch.stack([ids % w, ids // w], -1).to(torch.float32)
    rays = rays_for_pixels(uv, src.intr, T_world_src)
    out = render_rays(model, beta, rays, render, jitter=False, depth_only=True)
    keep = (out.opacity > min_opacity) & (out.depth > 0)
    X = rays.origins + rays.dirs * out.ray_dist[:, None]
    uv_dst = uv + flow.reshape(-1, 2)[ids]
    return X[keep].double().cpu().numpy(), uv_dst[keep].double().cpu().numpy()


def pose_from_flows(sources: list[tuple[MapFrame, torch.Tensor]], dst: MapFrame, T_guess: torch.Tensor,
                    model, beta, render: RenderConfig, n_per_source: int, gen: torch.Generator):
    """T_world_cam of `dst` (as `T_guess`'s dtype/device) from the flows of `sources`
    ((frame, T_world_cam) pairs) to it, or None when no PnP solution has enough inliers."""
    found = [c for f, T in sources
             if (c := flow_points(f, T, dst.index, model, beta, render, n_per_source, gen)) is not None]
    if not found:
        return None
    res = pnp_pose(*(np.concatenate(parts) for parts in zip(*found)), dst.intr, T_guess.double().cpu().numpy())
    if res is None:
        return None
    return torch.as_tensor(res[0], dtype=T_guess.dtype, device=T_guess.device)

