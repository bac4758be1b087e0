"""The labelled `oracle` priors: derived from ground truth, for evaluation and tests only.

`oracle` (the default) imitates the errors of a monocular network of the Omnidata / DPT class
on indoor scenes; `oracle:clean` is nearly GT, for debugging only (`OracleCorruption.clean`).

Depth: GT z-depth with invalid pixels filled (nearest valid), blurred edges, a smooth
multiplicative distortion field, noise, and a random per-frame affine map (scale in [0.5, 2],
positive shift): as ambiguous as a monocular prediction. Normals: from the GT depth blurred
(rounded edges), tilted by a smooth random field plus noise. The fields live on the scene's
points (world frame, GT pose), so every view of a place shares its error, as a network's errors
are consistent across views; they and the per-frame draws follow the run's config `seed`. Flow: GT depth + GT poses, with
occlusion and out-of-image pixels marked invalid (`--flow oracle`; realistic runs use DIS).

Published error statistics the realistic defaults follow, after per-image scale-and-shift
alignment (depth) or as raw angles (normals):
- Depth AbsRel 0.08-0.11 on NYUv2 zero-shot for DPT / MiDaS v3 (Ranftl et al., "Vision
  Transformers for Dense Prediction", ICCV 2021, Table 1; Eftekhar et al., "Omnidata",
  ICCV 2021 reports the same class of errors). Here: a field of 12% std over 0.25 m of the
  scene (clipped at 2.5 std) plus 2% noise, inside that range on the Replica clip and the
  synthetic room (`tests/nicer_stream/priors/test_oracle.py` checks it; docs/decisions.md).
- Depth edges: those networks predict at 384 px and are upsampled: discontinuities blur
  over a few pixels of the input (sigma 0.8% of the image width here: 2.6 px at 320 px).
- Normals: mean angular error 15-20 degrees on NYUv2 / ScanNet for Omnidata's normal model
  (Eftekhar et al. 2021; Bae et al., "Estimating and Exploiting the Aleatoric Uncertainty in
  Surface Normal Estimation", ICCV 2021, Table 1: 14.9-20 deg); here of that order (the same
  test; docs/decisions.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import torch

from nicer_stream.errors import UserError
from nicer_stream.geometry.camera import in_image, pixel_grid, project, unproject
from nicer_stream.geometry.se3 import invert, transform_points
from nicer_stream.priors.base import DepthNormal, DepthNormalProvider, FlowProvider
from nicer_stream.geometry.depth_normals import (fill_nearest, normals_from_depth, orient_towards_camera,
                                                unproject_depth)
from nicer_stream.types import FlowPrior, Frame, Intrinsics

_NEEDS_GT = (
    "the 'oracle' prior needs ground truth {what}, and frame {index} has none: "
    "use a source with GT (replica:, synthetic:, ...) or another prior (e.g. depth none, flow dis)"
)


@dataclass(frozen=True)
class OracleCorruption:
    """How the oracle degrades GT (the realistic defaults; `clean()` is the near-GT variant)."""

    scale_range: tuple[float, float] = (0.5, 2.0)
    """Per-frame scale of the relative depth (unknown to the SLAM)."""
    shift_range: tuple[float, float] = (0.0, 0.5)
    """Per-frame shift, as a fraction of the median depth times the scale."""
    blur_sigma_px: float = 1.0
    """Depth blur in pixels (at least; see `blur_sigma_frac`)."""
    blur_sigma_frac: float = 0.008
    """Depth blur as a fraction of the image width (edges blurred over several pixels)."""
    noise_rel: float = 0.02
    """Per-pixel depth noise std, relative to the median depth."""
    field_std: float = 0.12
    """Std of the smooth multiplicative depth distortion log(d'/d) (clipped at 2.5 std)."""
    field_length_m: float = 0.25
    """Length scale of the distortion and normal fields, in metres of the scene: a field over the
    scene's points (world frame), so every view of a place shares its error, as a network's do."""
    normal_blur_frac: float = 0.005
    """Normals come from the GT depth blurred by this fraction of the image width (rounded edges)."""
    normal_field_std: float = 0.1
    """Std of the smooth tangent tilt added to each normal (radians, roughly)."""
    normal_noise_std: float = 0.05
    """Std of the per-pixel tilt added to each normal."""

    @staticmethod
    def clean() -> "OracleCorruption":
        """`oracle:clean`: GT depth blurred by 1 px with 1% noise, exact normals (debugging only)."""
        return OracleCorruption(blur_sigma_frac=0.0, noise_rel=0.01, field_std=0.0, normal_blur_frac=0.0,
                                normal_field_std=0.0, normal_noise_std=0.0)

    @property
    def is_clean(self) -> bool:
        """No distortion field on depth nor tilt on normals: `oracle:clean`."""
        return self.field_std == 0 and self.normal_field_std == 0

    def describe(self) -> str:
        """One line for outputs: what this oracle imitates."""
        if self.is_clean:
            return "oracle:clean (GT depth, 1 px blur, 1% noise, GT normals; debugging only)"
        return (f"oracle (GT corrupted like a monocular network: smooth depth field {self.field_std:.0%}, "
                f"noise {self.noise_rel:.0%}, edge blur {self.blur_sigma_frac:.1%} of width, "
                f"per-frame scale/shift; normals tilted by {self.normal_field_std} rad smooth + "
                f"{self.normal_noise_std} noise)")


FIELD_FEATURES = 64
"""Random Fourier features of a scene field: enough for a smooth field of unit variance."""


def scene_field(points: np.ndarray, seed: int, stream: int, length_m: float, channels: int = 1) -> np.ndarray:
    """(..., 3) points -> (..., channels) float32 smooth random field of unit variance with a
    Gaussian correlation of length `length_m`, the same for every frame of a scene and `seed`
    (random Fourier features; `stream` tells the fields of one seed apart)."""
    rng = np.random.default_rng([seed, 1_000_003, stream])
    w = rng.normal(0.0, 1.0 / length_m, size=(channels, FIELD_FEATURES, 3))
    b = rng.uniform(0.0, 2 * np.pi, size=(channels, FIELD_FEATURES))
    x = points.reshape(-1, 3).astype(np.float64)
    out = np.sqrt(2.0 / FIELD_FEATURES) * np.cos(np.einsum("nd,ckd->nck", x, w) + b).sum(-1)
    return out.reshape(*points.shape[:-1], channels).astype(np.float32)


def world_points(depth: np.ndarray, intr: Intrinsics, T_world_cam: np.ndarray | None) -> np.ndarray:
    """(H, W) z-depth -> (H, W, 3) points in the world frame (the camera's without a pose)."""
    p = torch.from_numpy(unproject_depth(depth, intr))
    if T_world_cam is not None:
        p = transform_points(torch.from_numpy(np.asarray(T_world_cam, dtype=np.float64)), p)
    return p.numpy()


def fill_invalid_nearest(depth: np.ndarray) -> np.ndarray:
    """(H, W) float32 depth with 0/non-finite pixels replaced by the nearest valid one."""
    if not (np.isfinite(depth) & (depth > 0)).any():
        raise UserError("the 'oracle' prior got a GT depth image with no valid pixel: check the source's depth files")
    return fill_nearest(depth)


def corrupt_depth(depth: np.ndarray, rng: np.random.Generator, c: OracleCorruption,
                  field: np.ndarray | None = None) -> np.ndarray:
    """(H, W) filled metric depth -> (H, W) float32 relative depth
    s * (blur(d) * exp(field_std * field) + noise) + t, `field` (H, W) of unit std (the scene's
    at the frame's points); the noise, s and t drawn from `rng` (per frame)."""
    med = float(np.median(depth))
    sigma = max(c.blur_sigma_px, c.blur_sigma_frac * depth.shape[1])
    d = cv2.GaussianBlur(depth.astype(np.float32), (0, 0), sigma) if sigma > 0 else depth
    if c.field_std > 0 and field is not None:
        d = d * np.exp(c.field_std * np.clip(field, -2.5, 2.5))
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


def corrupt_normals(depth: np.ndarray, intr: Intrinsics, rng: np.random.Generator, c: OracleCorruption,
                    tilt_field: np.ndarray | None = None) -> np.ndarray:
    """(H, W) filled metric depth -> (H, W, 3) float32 unit camera-frame normals facing the
    camera: from the depth blurred by `normal_blur_frac` of the width, tilted by `tilt_field`
    (H, W, 3) camera-frame vectors of unit std (the scene's) plus per-pixel noise."""
    sigma = c.normal_blur_frac * depth.shape[1]
    d = cv2.GaussianBlur(depth.astype(np.float32), (0, 0), sigma) if sigma > 0 else depth
    n = normals_from_depth(d, intr)
    if c.normal_field_std == 0 and c.normal_noise_std == 0:
        return n
    tilt = c.normal_field_std * (tilt_field if tilt_field is not None else np.zeros_like(n))
    tilt = tilt + rng.normal(0.0, c.normal_noise_std, size=tilt.shape).astype(np.float32)
    n = n + tilt
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-9)
    # Still facing the camera (a network predicts visible sides).
    return orient_towards_camera(n, intr).astype(np.float32)


class OracleDepthNormal(DepthNormalProvider):
    """`oracle` depth + normals from GT depth: the errors of one place shared by every view of it
    (fields over the scene's points, GT pose), the per-frame scale, shift and noise drawn per
    (seed, frame index); `seed` is the run's config `seed`."""

    name = "oracle"

    def __init__(self, seed: int = 0, corruption: OracleCorruption = OracleCorruption()) -> None:
        self.seed = seed
        self.corruption = corruption
        self.name = "oracle:clean" if corruption.is_clean else "oracle"
        self.description = corruption.describe()

    def predict(self, frame: Frame) -> DepthNormal:
        if frame.gt_depth is None:
            raise UserError(_NEEDS_GT.format(what="depth", index=frame.index))
        filled = fill_invalid_nearest(frame.gt_depth)
        rng = np.random.default_rng([self.seed, frame.index])
        c = self.corruption
        field = tilt = None
        if c.field_std > 0 or c.normal_field_std > 0:
            pts = world_points(filled, frame.intrinsics, frame.gt_pose)
            field = scene_field(pts, self.seed, 0, c.field_length_m)[..., 0]
            tilt = scene_field(pts, self.seed, 1, c.field_length_m, 3)
            if frame.gt_pose is not None:  # world-frame tilt vectors seen from this camera
                tilt = tilt @ np.asarray(frame.gt_pose, dtype=np.float32)[:3, :3]
        return DepthNormal(depth=corrupt_depth(filled, rng, c, field),
                           normal=corrupt_normals(filled, frame.intrinsics, rng, c, tilt))


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
        return FlowPrior(src.index, dst.index, *flow_from_depth_pose(src.gt_depth, src.gt_pose, src.intrinsics,
                                                                     dst.gt_pose, dst.intrinsics, dst.gt_depth,
                                                                     self.occlusion_tol))
