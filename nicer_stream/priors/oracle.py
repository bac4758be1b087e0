"""The labelled `oracle` priors: derived from ground truth, for evaluation and tests only.

`oracle` (the default) imitates the errors of a monocular network of the Omnidata / DPT class
on indoor scenes; `oracle:clean` is nearly GT, for debugging only (`OracleCorruption.clean`).

Depth: GT z-depth with invalid pixels filled (nearest valid), blurred edges, a smooth
multiplicative distortion field, noise, and a random per-frame affine map (scale in [0.5, 2],
positive shift): as ambiguous as a monocular prediction. Normals: from the GT depth blurred
(rounded edges), tilted by a smooth random field plus noise. Flow: GT depth + GT poses, with
occlusion and out-of-image pixels marked invalid (`--flow oracle`; realistic runs use DIS).

Published error statistics the realistic defaults follow, after per-image scale-and-shift
alignment (depth) or as raw angles (normals):
- Depth AbsRel 0.08-0.11 on NYUv2 zero-shot for DPT / MiDaS v3 (Ranftl et al., "Vision
  Transformers for Dense Prediction", ICCV 2021, Table 1; Eftekhar et al., "Omnidata",
  ICCV 2021 reports the same class of errors). Here: a smooth field of 9% std (clipped at
  +-22%) plus 2% noise gives AbsRel 0.071 on the Replica clip, 0.076 on the synthetic room
  (`tests/nicer_stream/priors/test_oracle.py` measures it).
- Depth edges: those networks predict at 384 px and are upsampled: discontinuities blur
  over a few pixels of the input (sigma 0.8% of the image width here: 2.6 px at 320 px).
- Normals: mean angular error 15-20 degrees on NYUv2 / ScanNet for Omnidata's normal model
  (Eftekhar et al. 2021; Bae et al., "Estimating and Exploiting the Aleatoric Uncertainty in
  Surface Normal Estimation", ICCV 2021, Table 1: 14.9-20 deg); here 17.0 degrees on the
  Replica clip, 13.4 on the synthetic room (measured by the same test).
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
from nicer_stream.geometry.depth_normals import fill_nearest, normals_from_depth, orient_towards_camera
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
    field_std: float = 0.09
    """Std of the smooth multiplicative depth distortion log(d'/d) (clipped at 2.5 std)."""
    field_cells: int = 4
    """The distortion and normal fields vary over about this many cells across the image."""
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


def smooth_field(shape: tuple[int, int], cells: int, rng: np.random.Generator, channels: int = 1) -> np.ndarray:
    """(H, W, channels) float32 random field of unit std that varies over ~`cells` cells across
    the image: Gaussian values on a coarse grid, resized bicubically."""
    h, w = shape
    gh, gw = max(2, round(cells * h / max(h, w)) + 1), cells + 1
    coarse = rng.normal(size=(gh, gw, channels)).astype(np.float32)
    out = cv2.resize(coarse, (w, h), interpolation=cv2.INTER_CUBIC).reshape(h, w, channels)
    return out / max(float(out.std()), 1e-6)


def fill_invalid_nearest(depth: np.ndarray) -> np.ndarray:
    """(H, W) float32 depth with 0/non-finite pixels replaced by the nearest valid one."""
    if not (np.isfinite(depth) & (depth > 0)).any():
        raise UserError("the 'oracle' prior got a GT depth image with no valid pixel: check the source's depth files")
    return fill_nearest(depth)


def corrupt_depth(depth: np.ndarray, rng: np.random.Generator, c: OracleCorruption) -> np.ndarray:
    """(H, W) filled metric depth -> (H, W) float32 relative depth
    s * (blur(d) * exp(field) + noise) + t."""
    med = float(np.median(depth))
    sigma = max(c.blur_sigma_px, c.blur_sigma_frac * depth.shape[1])
    d = cv2.GaussianBlur(depth.astype(np.float32), (0, 0), sigma) if sigma > 0 else depth
    if c.field_std > 0:
        f = np.clip(smooth_field(d.shape, c.field_cells, rng)[..., 0], -2.5, 2.5)
        d = d * np.exp(c.field_std * f)
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


def corrupt_normals(depth: np.ndarray, intr: Intrinsics, rng: np.random.Generator, c: OracleCorruption) -> np.ndarray:
    """(H, W) filled metric depth -> (H, W, 3) float32 unit camera-frame normals facing the
    camera: from the depth blurred by `normal_blur_frac` of the width, tilted by a smooth
    random field plus per-pixel noise."""
    sigma = c.normal_blur_frac * depth.shape[1]
    d = cv2.GaussianBlur(depth.astype(np.float32), (0, 0), sigma) if sigma > 0 else depth
    n = normals_from_depth(d, intr)
    if c.normal_field_std == 0 and c.normal_noise_std == 0:
        return n
    tilt = c.normal_field_std * smooth_field(depth.shape, c.field_cells, rng, 3)
    tilt += rng.normal(0.0, c.normal_noise_std, size=tilt.shape).astype(np.float32)
    n = n + tilt
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-9)
    # Still facing the camera (a network predicts visible sides).
    return orient_towards_camera(n, intr).astype(np.float32)


class OracleDepthNormal(DepthNormalProvider):
    """`oracle` depth + normals from GT depth; deterministic per (seed, frame index)."""

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
        return DepthNormal(
            depth=corrupt_depth(filled, rng, self.corruption),
            normal=corrupt_normals(filled, frame.intrinsics, rng, self.corruption),
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
