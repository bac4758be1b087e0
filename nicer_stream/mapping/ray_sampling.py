"""Random pixels over a set of frames, as one ray batch."""
from __future__ import annotations

from dataclasses import dataclass

import torch

from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.render.renderer import RayBatch, rays_for_pixels


@dataclass
class FrameRays:
    """Rays of one frame inside a batch: slice [start, stop), pixels uv (n, 2), linear ids (n,)."""

    frame: MapFrame
    T_world_cam: torch.Tensor
    start: int
    stop: int
    uv: torch.Tensor
    pix: torch.Tensor


def sample_pixels(frame: MapFrame, n: int, gen: torch.Generator | None = None):
    """n random pixels of `frame` -> (uv (n, 2) float pixel centres, linear ids (n,))."""
    h, w = frame.intr.height, frame.intr.width
    pix = torch.randint(0, h * w, (n,), generator=gen, device="cpu").to(frame.rgb.device)
    uv = torch.stack([pix % w, pix // w], -1).to(torch.float32)
    return uv, pix


def batch_rays(frames: list[MapFrame], poses: list[torch.Tensor], total: int, gen=None):
    """~`total` rays spread evenly over `frames` at `poses` (T_world_cam, maybe differentiable).

    Returns (RayBatch, list[FrameRays]).
    """
    per = max(1, total // len(frames))
    parts, layout, start = [], [], 0
    for f, T in zip(frames, poses):
        uv, pix = sample_pixels(f, per, gen)
        parts.append(rays_for_pixels(uv, f.intr, T))
        layout.append(FrameRays(f, T, start, start + per, uv, pix))
        start += per
    rays = RayBatch(
        torch.cat([p.origins for p in parts]), torch.cat([p.dirs for p in parts]), torch.cat([p.z_per_dist for p in parts])
    )
    return rays, layout
