"""The labelled `oracle` priors: derived from ground truth, for evaluation and tests only.

Depth: GT z-depth with invalid pixels filled (nearest valid), Gaussian blur,
noise and a random per-frame affine map (scale in [0.5, 2], positive shift),
so that it is as ambiguous as a monocular prediction. Normals: from the filled
GT depth (camera frame, facing the camera). Flow: GT depth + GT poses, with
occlusion and out-of-image pixels marked invalid.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import torch
from scipy import ndimage

from nicer_stream.errors import UserError
from nicer_stream.geometry.camera import in_image, pixel_grid, project, unproject
from nicer_stream.geometry.se3 import invert, transform_points
from nicer_stream.priors.base import DepthNormal, DepthNormalProvider, FlowProvider
from nicer_stream.priors.normals_from_depth import normals_from_depth
from nicer_stream.types import FlowPrior, Frame, Intrinsics

_NEEDS_GT = (
    "the 'oracle' prior needs ground truth {what}, and frame {index} has none: "
    "use a source with GT (replica:, synthetic:, ...) or another provider (e.g. --provider none / --flow dis)"
)


@dataclass(frozen=True)
class OracleCorruption:
    """How the oracle degrades GT depth (std and shift relative to the median depth)."""

    scale_range: tuple[float, float] = (0.5, 2.0)
    shift_range: tuple[float, float] = (0.0, 0.5)
    blur_sigma_px: float = 1.0
    noise_rel: float = 0.01


def fill_invalid_nearest(depth: np.ndarray) -> np.ndarray:
    """(H, W) float32 depth with 0/non-finite pixels replaced by the nearest valid one."""
    bad = ~(np.isfinite(depth) & (depth > 0))
    if not bad.any():
        return depth.astype(np.float32)
    if bad.all():
        raise UserError("the 'oracle' prior got a GT depth image with no valid pixel: check the source's depth files")
    idx = ndimage.distance_transform_edt(bad, return_distances=False, return_indices=True)
    return depth[idx[0], idx[1]].astype(np.float32)


def corrupt_depth(depth: np.ndarray, rng: np.random.Generator, c: OracleCorruption) -> np.ndarray:
    """(H, W) filled metric depth -> (H, W) float32 relative depth s * (blur(d) + noise) + t."""
    med = float(np.median(depth))
    d = cv2.GaussianBlur(depth.astype(np.float32), (0, 0), c.blur_sigma_px) if c.blur_sigma_px > 0 else depth
    d = d + rng.normal(0.0, c.noise_rel * med, size=d.shape).astype(np.float32)
    s = rng.uniform(*c.scale_range)
    t = rng.uniform(*c.shift_range) * med * s
    return (s * d + t).astype(np.float32)


def flow_from_depth_pose(
    depth_src: np.ndarray,
    T_world_src: np.ndarray,
    intr_src: Intrinsics,
    T_world_dst: np.ndarray,
    intr_dst: Intrinsics,
    depth_dst: np.ndarray | None = None,
    occlusion_tol: float = 0.05,
) -> tuple[np.ndarray, np.ndarray]:
    """Flow from projecting each source pixel's GT 3D point into the destination camera.

    depth_src: (H, W) z-depth in metres (0 invalid); T_world_*: (4, 4) camera-to-world.
    depth_dst: destination GT depth; where given, a pixel whose projected depth differs
        from it by more than `occlusion_tol` (relative) is occluded.
    Returns flow (H, W, 2) float32 (du, dv) pixels and valid (H, W) bool.
    """
    h, w = depth_src.shape
    uv = pixel_grid(intr_src, dtype=torch.float64)
    z_src = torch.from_numpy(depth_src.astype(np.float64)).reshape(-1)
    p_src = unproject(uv, z_src, intr_src)
    T_dst_src = invert(torch.from_numpy(T_world_dst).double()) @ torch.from_numpy(T_world_src).double()
    uv_dst, z_dst = project(transform_points(T_dst_src, p_src), intr_dst)
    valid = (z_src > 0) & (z_dst > 1e-6) & in_image(uv_dst, intr_dst)
    if depth_dst is not None:
        # Nearest destination pixel: its GT depth must match the projected depth.
        col = uv_dst[:, 0].round().clamp(0, intr_dst.width - 1).long()
        row = uv_dst[:, 1].round().clamp(0, intr_dst.height - 1).long()
        seen = torch.from_numpy(depth_dst.astype(np.float64))[row, col]
        valid &= (seen > 0) & ((z_dst - seen).abs() <= occlusion_tol * seen)
    flow = (uv_dst - uv).reshape(h, w, 2).numpy().astype(np.float32)
    return flow, valid.reshape(h, w).numpy()


class OracleDepthNormal(DepthNormalProvider):
    """`oracle` depth + normals from GT depth; deterministic per (seed, frame index)."""

    name = "oracle"

    def __init__(self, seed: int = 0, corruption: OracleCorruption = OracleCorruption()) -> None:
        self.seed = seed
        self.corruption = corruption

    def predict(self, frame: Frame) -> DepthNormal:
        if frame.gt_depth is None:
            raise UserError(_NEEDS_GT.format(what="depth", index=frame.index))
        filled = fill_invalid_nearest(frame.gt_depth)
        rng = np.random.default_rng([self.seed, frame.index])
        return DepthNormal(
            depth=corrupt_depth(filled, rng, self.corruption),
            normal=normals_from_depth(filled, frame.intrinsics),
        )


class OracleFlow(FlowProvider):
    """`oracle` flow from GT depth and GT poses (occlusion-checked against the destination's GT depth)."""

    name = "oracle"

    def __init__(self, occlusion_tol: float = 0.05) -> None:
        self.occlusion_tol = occlusion_tol

    def flow(self, src: Frame, dst: Frame) -> FlowPrior:
        for f in (src, dst):
            if f.gt_pose is None:
                raise UserError(_NEEDS_GT.format(what="poses", index=f.index))
        if src.gt_depth is None:
            raise UserError(_NEEDS_GT.format(what="depth", index=src.index))
        flow, valid = flow_from_depth_pose(
            src.gt_depth, src.gt_pose, src.intrinsics, dst.gt_pose, dst.intrinsics, dst.gt_depth, self.occlusion_tol
        )
        return FlowPrior(src.index, dst.index, flow, valid)
