"""Pinhole camera maths (torch; `project_world` is its numpy counterpart for world points). OpenCV axes: x right, y down, z forward.

Integer pixel coordinates are pixel centres. `depth` is z-depth along the
camera's optical axis; `ray_dist` is the distance along a (unit) ray. For a
unit ray direction d in the camera frame, depth = ray_dist * d_z.
"""
from __future__ import annotations

import numpy as np
import torch

from nicer_stream.types import Intrinsics


def pixel_grid(intr: Intrinsics, device=None, dtype=torch.float32) -> torch.Tensor:
    """(H*W, 2) pixel coordinates (u, v) in row-major order."""
    v, u = torch.meshgrid(
        torch.arange(intr.height, device=device, dtype=dtype),
        torch.arange(intr.width, device=device, dtype=dtype),
        indexing="ij",
    )
    return torch.stack([u.reshape(-1), v.reshape(-1)], dim=-1)


def camera_dirs(uv: torch.Tensor, intr: Intrinsics) -> torch.Tensor:
    """(N, 2) pixels -> (N, 3) camera-frame directions with z = 1 (not unit)."""
    x = (uv[:, 0] - intr.cx) / intr.fx
    y = (uv[:, 1] - intr.cy) / intr.fy
    return torch.stack([x, y, torch.ones_like(x)], dim=-1)


def rays_world(uv: torch.Tensor, intr: Intrinsics, T_world_cam: torch.Tensor):
    """Rays through pixels `uv` (N, 2) of a camera at `T_world_cam` (4, 4).

    Returns (origins (N, 3), unit directions (N, 3), z_per_dist (N,)) in world
    coordinates; z_per_dist converts a ray distance into z-depth. Differentiable
    with respect to T_world_cam.
    """
    d_cam = camera_dirs(uv, intr).to(T_world_cam.dtype)
    norm = d_cam.norm(dim=-1)
    d_cam = d_cam / norm[:, None]
    d_world = d_cam @ T_world_cam[:3, :3].transpose(0, 1)
    origins = T_world_cam[:3, 3].expand_as(d_world)
    return origins, d_world, d_cam[:, 2]


def project(p_cam: torch.Tensor, intr: Intrinsics):
    """(N, 3) camera-frame points -> (N, 2) pixels and (N,) z-depth."""
    z = p_cam[:, 2]
    zs = z.clamp_min(1e-6)
    u = intr.fx * p_cam[:, 0] / zs + intr.cx
    v = intr.fy * p_cam[:, 1] / zs + intr.cy
    return torch.stack([u, v], dim=-1), z


def project_world(T_world_cam: np.ndarray, X: np.ndarray, intr: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """numpy: world points (N, 3) -> (pixels (N, 2), z-depth (N,)) in the camera at `T_world_cam`
    (float64; the sparse, non-differentiable side: the frontend, stereo and keyframe checks)."""
    T_cw = np.linalg.inv(T_world_cam)
    p = X @ T_cw[:3, :3].T + T_cw[:3, 3]
    z = p[:, 2]
    zs = np.where(np.abs(z) < 1e-9, 1e-9, z)
    uv = np.stack([intr.fx * p[:, 0] / zs + intr.cx, intr.fy * p[:, 1] / zs + intr.cy], -1)
    return uv, z


def unproject_world(T_world_cam: np.ndarray, uv: np.ndarray, z: np.ndarray, intr: Intrinsics) -> np.ndarray:
    """numpy, the inverse of `project_world`: pixels (N, 2) at z-depth (N,) in the camera at
    `T_world_cam` (4, 4) -> world points (N, 3) float64."""
    p = np.stack([(uv[:, 0] - intr.cx) / intr.fx, (uv[:, 1] - intr.cy) / intr.fy, np.ones(len(uv))], -1) * z[:, None]
    return p @ T_world_cam[:3, :3].T + T_world_cam[:3, 3]


def unproject(uv: torch.Tensor, depth: torch.Tensor, intr: Intrinsics) -> torch.Tensor:
    """(N, 2) pixels with (N,) z-depth -> (N, 3) camera-frame points."""
    return camera_dirs(uv, intr).to(depth.dtype) * depth[:, None]


def in_image(uv: torch.Tensor, intr: Intrinsics, margin: float = 0.0) -> torch.Tensor:
    """(N,) bool: pixel inside the image (pixel-centre convention)."""
    return (
        (uv[:, 0] >= -0.5 + margin)
        & (uv[:, 0] <= intr.width - 0.5 - margin)
        & (uv[:, 1] >= -0.5 + margin)
        & (uv[:, 1] <= intr.height - 0.5 - margin)
    )
