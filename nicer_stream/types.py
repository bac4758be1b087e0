"""Typed data passed between stages. Conventions: docs/conventions.md.

Frames carry numpy arrays (I/O side); the model works on torch tensors.
Ground-truth fields (`gt_pose`, `gt_depth`) exist for evaluation, sinks and
the labelled `oracle` prior provider only: nothing in the SLAM loop reads them.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics of an image of `width` x `height` pixels.

    OpenCV convention: integer pixel coordinates are pixel centres, so the
    top-left pixel's centre is (0, 0) and the image spans [-0.5, W-0.5].
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    def __post_init__(self) -> None:
        if not (self.fx > 0 and self.fy > 0 and self.width > 0 and self.height > 0):
            raise ValueError(f"invalid intrinsics {self}: focal lengths and size must be positive")

    def resized(self, width: int, height: int) -> "Intrinsics":
        """Intrinsics of the same camera after resizing the image to `width` x `height`."""
        sx, sy = width / self.width, height / self.height
        return Intrinsics(
            fx=self.fx * sx,
            fy=self.fy * sy,
            cx=(self.cx + 0.5) * sx - 0.5,
            cy=(self.cy + 0.5) * sy - 0.5,
            width=int(width),
            height=int(height),
        )

    def scaled(self, factor: float) -> "Intrinsics":
        """Intrinsics after resizing by `factor` (rounded to whole pixels)."""
        return self.resized(max(1, round(self.width * factor)), max(1, round(self.height * factor)))

    def matrix(self) -> np.ndarray:
        """(3, 3) K matrix, float64."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class DetailImage:
    """A frame's image at a higher resolution than `Frame.rgb`, for the geometric frontend: feature
    positions to a fraction of the map image's pixel make its poses several times more accurate
    (docs/priors.md, "The frontend at the source's resolution").

    grey: (h, w) uint8 luminance; intrinsics: of this image (the same camera as `Frame.rgb`'s)."""

    grey: np.ndarray
    intrinsics: Intrinsics


@dataclass
class Frame:
    """One input image and what the source knows about it.

    rgb: (H, W, 3) float32 in [0, 1], RGB order.
    gt_pose: (4, 4) T_world_cam float64, or None. Evaluation/sinks/oracle only.
    gt_depth: (H, W) float32 z-depth in metres (0 = invalid), or None. Evaluation/oracle only.
    """

    index: int
    timestamp: float
    rgb: np.ndarray
    intrinsics: Intrinsics
    gt_pose: np.ndarray | None = None
    gt_depth: np.ndarray | None = None
    name: str = ""
    timestamp_ns: int | None = None
    """Exact sensor time in integer nanoseconds when the source has one (MCAP stamps);
    `timestamp` (float seconds) cannot hold epoch times to the nanosecond."""
    detail: DetailImage | None = None
    """The same image larger than `rgb` (`SourceOptions.detail_side`), or None: the frontend then
    works on `rgb`."""

    @property
    def height(self) -> int:
        return int(self.rgb.shape[0])

    @property
    def width(self) -> int:
        return int(self.rgb.shape[1])

    def without_ground_truth(self) -> "Frame":
        """The same frame with GT removed: what the SLAM loop is given."""
        return replace(self, gt_pose=None, gt_depth=None)


@dataclass(frozen=True)
class FlowPrior:
    """Optical flow from frame `src_index` to frame `dst_index`.

    flow: (H, W, 2) float32 pixel displacement (du, dv): pixel (u, v) of the
        source image is seen at (u + du, v + dv) in the destination image.
    valid: (H, W) bool, False where the flow is unreliable (occluded, inconsistent).
    """

    src_index: int
    dst_index: int
    flow: np.ndarray
    valid: np.ndarray


@dataclass
class Priors:
    """Monocular priors of one frame, from the provider named `provider`.

    depth: (H, W) float32 relative depth (unknown scale and shift), or None.
    normal: (H, W, 3) float32 unit normals in the camera frame (OpenCV axes),
        facing the camera, or None.
    flows: optical flow to other frames.
    """

    frame_index: int
    provider: str
    depth: np.ndarray | None = None
    normal: np.ndarray | None = None
    flows: list[FlowPrior] = field(default_factory=list)
