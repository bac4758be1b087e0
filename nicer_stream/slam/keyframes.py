"""Which frames become keyframes: by what the camera saw, not by frame count. A frame is a
keyframe when the view has changed since the last keyframe (few of its tracks still seen, or a
baseline / rotation that is a fair share of the scene), or when `max_gap_s` seconds have passed
(a camera that never stops changing slowly); so the same scene at 30 Hz and at 10 Hz gives a
similar set. Each decision carries its reason (`summary.json`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ViewChange:
    """How far a frame's view is from the last keyframe's: the share of that keyframe's tracks
    still seen, the baseline over the scene's median depth, the rotation in degrees, seconds."""

    overlap: float
    baseline: float
    rotation_deg: float
    gap_s: float


def view_change(ids_kf: np.ndarray, T_kf: np.ndarray, t_kf: float, ids: np.ndarray, T: np.ndarray, t: float,
                depth: float) -> ViewChange:
    """The change from the keyframe (track ids (M,), T_world_cam (4, 4), timestamp) to a frame;
    `depth`: the scene's median depth in the poses' unit."""
    overlap = float(np.isin(ids_kf, ids).mean()) if len(ids_kf) else 0.0
    d = np.linalg.inv(T_kf) @ T
    angle = float(np.degrees(np.arccos(np.clip((np.trace(d[:3, :3]) - 1) / 2, -1.0, 1.0))))
    baseline = float(np.linalg.norm(d[:3, 3])) / depth if depth > 0 else 0.0
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
            return f"{100 * c.overlap:.0f}% of the last keyframe's tracks still seen"
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
        self.last: tuple[np.ndarray, np.ndarray, float] | None = None  # (track ids, T_world_cam, timestamp)
        self.reasons: dict[int, str] = {}

    def decide(self, ids: np.ndarray | None, T: np.ndarray, t: float, depth: float | None) -> str | None:
        """Why this frame (its track ids, or None without tracks; T_world_cam; timestamp; scene
        depth or None) should be a keyframe, or None. Without tracks or depth, only the time cap."""
        if self.last is None:
            return "first frame"
        ids_kf, T_kf, t_kf = self.last
        if ids is None or not depth:
            gap = t - t_kf
            return f"{gap:.1f} s since the last keyframe" if gap >= self.rule.max_gap_s else None
        return self.rule.reason(view_change(ids_kf, T_kf, t_kf, ids, T, t, depth))

    def taken(self, index: int, ids: np.ndarray | None, T: np.ndarray, t: float, reason: str) -> None:
        """Frame `index` became a keyframe (for `reason`): later frames compare with it."""
        self.last = (np.zeros(0, np.int64) if ids is None else ids, T, t)
        self.reasons[index] = reason
