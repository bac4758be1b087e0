"""Which frames become keyframes: by what the camera saw, not by frame count. A frame is a
keyframe when the view has changed since the last keyframe (few of its landmarks still in view,
or a baseline / rotation that is a fair share of the scene), or when `max_gap_s` seconds have
passed (a camera that never stops changing slowly); so the same scene at 30 Hz and at 10 Hz
gives a similar set. Each decision carries its reason (`summary.json`).

In view means projected inside the image in front of the camera: which keypoints a real frame's
detector finds again is too noisy a measure (half of them are not matched in the next frame)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nicer_stream.frontend.health import pose_step
from nicer_stream.geometry.camera import project_world as project
from nicer_stream.types import Intrinsics


@dataclass(frozen=True)
class ViewChange:
    """How far a frame's view is from the last keyframe's: the share of that keyframe's landmarks
    still in view, the baseline over the scene's median depth, the rotation in degrees, seconds."""

    overlap: float
    baseline: float
    rotation_deg: float
    gap_s: float


def in_view(points: np.ndarray, T: np.ndarray, intr: Intrinsics) -> np.ndarray:
    """(N,) bool: world points (N, 3) in front of the camera at T_world_cam (4, 4) and inside its image."""
    uv, z = project(T, points, intr)
    return (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] <= intr.width - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= intr.height - 1)


def view_change(points_kf: np.ndarray, T_kf: np.ndarray, t_kf: float, T: np.ndarray, t: float, depth: float,
                intr: Intrinsics) -> ViewChange:
    """The change from the keyframe (its landmarks (M, 3) world, T_world_cam (4, 4), timestamp) to
    a frame at T (timestamp t); `depth`: the scene's median depth in the poses' unit."""
    overlap = float(in_view(points_kf, T, intr).mean()) if len(points_kf) else 0.0
    dist, angle = pose_step(T_kf, T)
    baseline = dist / depth if depth > 0 else 0.0
    return ViewChange(overlap, baseline, angle, t - t_kf)


@dataclass(frozen=True)
class KeyframeRule:
    """The thresholds (`[mapping]` keyframe_* fields)."""

    min_overlap: float = 0.6
    max_baseline: float = 0.1
    max_rotation_deg: float = 15.0
    max_gap_s: float = 1.0
    min_gap_s: float = 0.0

    def reason(self, c: ViewChange) -> str | None:
        """Why a frame with view change `c` is a keyframe, or None."""
        if c.gap_s < self.min_gap_s:
            return None
        if c.overlap < self.min_overlap:
            return f"{100 * c.overlap:.0f}% of the last keyframe's landmarks still in view"
        if c.baseline > self.max_baseline:
            return f"baseline {c.baseline:.2f} of the scene depth"
        if c.rotation_deg > self.max_rotation_deg:
            return f"rotated {c.rotation_deg:.0f} deg"
        if c.gap_s >= self.max_gap_s:
            return f"{c.gap_s:.1f} s since the last keyframe"
        return None


class KeyframeSelector:
    """Remembers the last keyframe's view and decides for each new frame; `reasons` holds why
    every keyframe was taken."""

    def __init__(self, rule: KeyframeRule) -> None:
        self.rule = rule
        self.last: tuple[np.ndarray | None, np.ndarray, float] | None = None  # (landmarks, T_world_cam, timestamp)
        self.reasons: dict[int, str] = {}

    def decide(self, T: np.ndarray, t: float, depth: float | None, intr: Intrinsics | None) -> str | None:
        """Why a frame at T_world_cam `T`, timestamp `t` (the scene depth, or None; the intrinsics of
        the image the landmarks are seen in) should be a keyframe, or None. Without landmarks or
        depth, only the time cap."""
        if self.last is None:
            return "first frame"
        points, T_kf, t_kf = self.last
        if points is None or not len(points) or not depth or intr is None:
            gap = t - t_kf
            return f"{gap:.1f} s since the last keyframe" if gap >= self.rule.max_gap_s else None
        return self.rule.reason(view_change(points, T_kf, t_kf, T, t, depth, intr))

    def taken(self, index: int, points: np.ndarray | None, T: np.ndarray, t: float, reason: str) -> None:
        """Frame `index` became a keyframe (for `reason`) with its landmarks `points` (M, 3) world
        (None: none yet): later frames compare with it."""
        self.last = (points, T, t)
        self.reasons[index] = reason
