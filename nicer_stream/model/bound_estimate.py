"""Choosing the scene bound without ground truth."""
from __future__ import annotations

import numpy as np

from nicer_stream.config import BoundConfig
from nicer_stream.geometry.camera import pixel_grid, unproject
from nicer_stream.model.bound import SceneBound, bound_from_points
from nicer_stream.types import Intrinsics

import torch


def bound_from_config(cfg: BoundConfig) -> SceneBound:
    return SceneBound(tuple(cfg.centre), cfg.half_extent, "config")


def bound_from_cameras(poses: np.ndarray, cfg: BoundConfig) -> SceneBound:
    """For known poses: a cube of the configured half extent centred half-way into the
    view of the average camera (mean centre + half_extent/2 along the mean optical axis)."""
    centres = poses[:, :3, 3]
    axis = poses[:, :3, 2].mean(0)
    axis /= max(np.linalg.norm(axis), 1e-9)
    c = centres.mean(0) + axis * cfg.half_extent / 2
    return SceneBound(tuple(float(v) for v in c), cfg.half_extent, "cameras")


def metric_points(depth_m: np.ndarray, intr: Intrinsics, T_world_cam: np.ndarray, cfg: BoundConfig) -> np.ndarray:
    """(N, 3) world points of a metric(-ised) depth map (H, W) (depths in (0, max_depth_m))
    plus the camera centre."""
    uv = pixel_grid(intr)
    d = torch.as_tensor(depth_m, dtype=torch.float32).reshape(-1)
    keep = (d > 0) & (d < cfg.max_depth_m) & torch.isfinite(d)
    p = unproject(uv[keep], d[keep], intr).numpy().astype(np.float64)
    p = p @ T_world_cam[:3, :3].T + T_world_cam[:3, 3]
    return np.concatenate([p, T_world_cam[None, :3, 3]])


def bound_from_depth(depth_m: np.ndarray, intr: Intrinsics, T_world_cam: np.ndarray, cfg: BoundConfig) -> SceneBound:
    """From a metric(-ised) depth map (H, W) of one frame: its points plus the camera
    centre, grown by `cfg.margin` and slid to leave room behind the camera (`bound_around`)."""
    return bound_around(metric_points(depth_m, intr, T_world_cam, cfg), T_world_cam[None, :3, 3], cfg, "depth_prior")


def bound_around(points: np.ndarray, cameras: np.ndarray, cfg: BoundConfig, source: str) -> SceneBound:
    """The SLAM's cube around its first (N, 3) world points, seen from (M, 3) camera centres, with
    `cfg`'s margin and its room behind the cameras (`bound_from_points`)."""
    return bound_from_points(points, cfg.margin, source, cameras, cfg.camera_margin, cfg.points_edge)
