"""Whether the classical frontend's pose of a frame can be believed, from evidence it carries
itself (no map, no ground truth): its landmarks must reproject where the frame sees them, its
pose must move when its tracks move (a frozen estimate), and the scene's depth in its unit must
not jump (a collapsing scale). Each failure becomes a `HealthReport` the SLAM logs, counts in
`summary.json` and acts on (the frame's pose then comes from the map, or the frame is lost)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from nicer_stream.geometry.camera import project_world as project
from nicer_stream.types import Intrinsics

KINDS = ("lost", "reprojection", "frozen", "scale")


@dataclass(frozen=True)
class HealthReport:
    """`kind` (one of KINDS) at frame `index`, with a one-line `message`."""

    index: int
    kind: str
    message: str

    def __str__(self) -> str:
        return f"frame {self.index}: frontend {self.kind}: {self.message}"


@dataclass(frozen=True)
class HealthLimits:
    """What counts as a failure."""

    reproj_px: float = 4.0
    """Median reprojection error of the frame's landmarks at the frontend's pose above this: its
    pose does not explain its own tracks (2x the PnP inlier bound)."""
    frozen_px: float = 2.0
    """Tracks moving by a median of this many pixels since the previous frame ..."""
    frozen_deg: float = 0.05
    """... while the pose rotated by less than this ..."""
    frozen_depth_frac: float = 0.002
    """... and moved less than this fraction of the scene's median depth: a frozen estimate."""
    frozen_frames: int = 3
    """Consecutive frames of that before a freeze is reported."""
    scale_ratio: float = 2.0
    """The frame's median landmark depth more than this factor from the recent median: a scale jump."""
    history: int = 30
    """Frames the recent median depth is taken over."""
    min_history: int = 5
    """Frames with a depth before the scale is judged (the first landmarks are few)."""


def reprojection_error(T_world_cam: np.ndarray, points: np.ndarray, uv: np.ndarray, intr: Intrinsics) -> float:
    """Median pixel distance between `uv` (N, 2) and the world `points` (N, 3) projected by
    T_world_cam (4, 4); inf when no point is in front of the camera."""
    px, z = project(T_world_cam, points, intr)
    ok = z > 0
    return float(np.median(np.linalg.norm(px[ok] - uv[ok], axis=1))) if ok.any() else float("inf")


def median_track_motion(ids_a: np.ndarray, uv_a: np.ndarray, ids_b: np.ndarray, uv_b: np.ndarray) -> float:
    """Median pixel displacement of the tracks two frames share ((M,) ids, (M, 2) pixels each); 0 if none."""
    _, ia, ib = np.intersect1d(ids_a, ids_b, return_indices=True)
    return float(np.median(np.linalg.norm(uv_a[ia] - uv_b[ib], axis=1))) if len(ia) else 0.0


def pose_step(T_a: np.ndarray, T_b: np.ndarray) -> tuple[float, float]:
    """(translation, rotation in degrees) between two T_world_cam (4, 4)."""
    d = np.linalg.inv(T_a) @ T_b
    angle = np.degrees(np.arccos(np.clip((np.trace(d[:3, :3]) - 1) / 2, -1.0, 1.0)))
    return float(np.linalg.norm(d[:3, 3])), float(angle)


@dataclass
class FrontendHealth:
    """Call `check` once per frame in input order with the frontend's pose of it (None: it had
    none); it returns the reports that frame raised. `reports` keeps them all."""

    limits: HealthLimits = field(default_factory=HealthLimits)
    reports: list[HealthReport] = field(default_factory=list)
    _depths: list[float] = field(default_factory=list)
    _still: int = 0
    _lost: bool = True  # nothing to lose before its first pose
    _prev: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # (T, ids, uv) of the previous frame

    def check(self, index: int, T: np.ndarray | None, ids: np.ndarray, uv: np.ndarray,
              landmark_uv: np.ndarray, landmarks: np.ndarray, intr: Intrinsics,
              median_depth: float | None) -> list[HealthReport]:
        """`ids`/`uv` (M,), (M, 2): the frame's tracks; `landmarks` (P, 3) world and `landmark_uv`
        (P, 2): those tracks with a landmark; `median_depth`: their median z-depth at T."""
        out: list[HealthReport] = []
        lim = self.limits
        if T is None:
            if not self._lost:
                out.append(HealthReport(index, "lost", f"no pose ({len(landmarks)} of {len(ids)} tracks have a landmark)"))
            self._lost, self._prev, self._still = True, None, 0
            self.reports += out
            return out
        self._lost = False
        if len(landmarks):
            err = reprojection_error(T, landmarks, landmark_uv, intr)
            if err > lim.reproj_px:
                out.append(HealthReport(index, "reprojection", f"its landmarks reproject {err:.1f} px from its tracks"))
        if self._prev is not None and median_depth:
            T0, ids0, uv0 = self._prev
            motion = median_track_motion(ids0, uv0, ids, uv)
            dist, angle = pose_step(T0, T)
            still = motion > lim.frozen_px and angle < lim.frozen_deg and dist < lim.frozen_depth_frac * median_depth
            self._still = self._still + 1 if still else 0
            if self._still == lim.frozen_frames:
                out.append(HealthReport(index, "frozen", f"pose still for {self._still} frames while its tracks "
                                                         f"moved {motion:.1f} px"))
        if median_depth and len(self._depths) >= lim.min_history:
            ref = float(np.median(self._depths))
            ratio = median_depth / ref
            if not 1 / lim.scale_ratio <= ratio <= lim.scale_ratio:
                out.append(HealthReport(index, "scale", f"scene depth {median_depth:.3g} is {ratio:.2f}x the recent "
                                                        f"{ref:.3g} (unit: the map's)"))
        if median_depth:
            self._depths = (self._depths + [median_depth])[-lim.history:]
        self._prev = (T, ids, uv)
        self.reports += out
        return out

    def counts(self) -> dict[str, int]:
        """Reports by kind, for `summary.json`."""
        return {k: sum(r.kind == k for r in self.reports) for k in KINDS}
