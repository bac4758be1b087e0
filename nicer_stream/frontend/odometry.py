"""The classical frontend as a visual odometry on its own (no map): the two-view start, then
each frame's PnP pose, trusted and triangulated from. What the SLAM's poses start from, and what
`scripts/frontend_bench.py` measures. Poses are T_world_cam (4, 4) float64, the first frame of
the start at the identity, the unit set by `median_m` (the first view's median tracked depth)."""
from __future__ import annotations

import numpy as np

from nicer_stream.config import FrontendConfig
from nicer_stream.frontend.frontend import ClassicalFrontend
from nicer_stream.types import Intrinsics


def constant_velocity(T1: np.ndarray, T0: np.ndarray) -> np.ndarray:
    """The next T_world_cam after T0 then T1 at the same relative motion (camera frame)."""
    return T1 @ np.linalg.inv(T0) @ T1


class FrontendOdometry:
    """Call `step` on every frame in input order; `poses` holds every frame placed so far and
    `reports` the frames it could not place (with the reason)."""

    def __init__(self, cfg: FrontendConfig, median_m: float = 2.0, init_max_frames: int = 60,
                 restart_after: int = 5) -> None:
        self.frontend = ClassicalFrontend(cfg)
        self.median_m, self.init_max_frames, self.restart_after = median_m, init_max_frames, restart_after
        self.held: list[int] = []
        self.anchor = np.eye(4)  # T_world_cam of the current start's first view
        self.lost_run = 0
        self.depth = median_m  # the scene's latest median depth, in the poses' unit
        self.poses: dict[int, np.ndarray] = {}
        self.order: list[int] = []
        self.reports: list[str] = []

    def step(self, index: int, image: np.ndarray, intr: Intrinsics) -> None:
        """Observe frame `index` ((H, W, 3) float RGB in [0, 1] or (H, W) uint8 grey) and place it."""
        self.frontend.observe(index, image, intr)
        if self.held or not self.poses:
            self._start(index)
            return
        self._place(index)
        if self.lost_run >= self.restart_after:
            self._restart(index)

    def _restart(self, index: int) -> None:
        """Lost for `restart_after` frames: a new two-view start from this frame, placed at its
        motion-model pose and scaled to the last scene depth (the frontend's landmarks are gone)."""
        self.reports.append(f"frame {index}: lost for {self.lost_run} frames: a new two-view start")
        self.frontend.landmarks.clear()
        self.frontend.parallax.clear()
        self.frontend.posed = []
        self.frontend.poses.clear()
        self.frontend.own.clear()
        self.frontend.archive.clear()
        self.frontend.anchors.clear()
        self.anchor, self.lost_run = self.poses[index], 0
        self.held = [index]
        self.frontend.pinned = {index}

    def _start(self, index: int) -> None:
        self.held.append(index)
        # A first view needs tracks to start from (not a blank or blurred-out frame).
        need = 2 * self.frontend.cfg.min_inliers
        while self.held and len(self.frontend.obs[self.held[0]][0]) < need:
            self.held.pop(0)
        # The start slides to the oldest held view that still shares enough tracks with this one.
        self.held = self.held[self.frontend.stale_first_views(self.held, index):]
        if not self.held:
            return
        self.frontend.pinned = {self.held[0]}
        if len(self.held) < 2:
            return
        view = self.frontend.two_view(self.held[0], index, self.depth)
        if view is None:
            if len(self.held) >= self.init_max_frames:
                self.reports.append(f"frame {self.held[0]}: no two-view start within {self.init_max_frames} frames")
                self.held = self.held[len(self.held) // 2:]
                self.anchor = self.poses.get(self.held[0], self.anchor)
                self.frontend.pinned = {self.held[0]}
            return
        first, held = self.held[0], self.held[1:-1]
        self.held, self.frontend.pinned = [], set()
        for k, T in ((first, self.anchor), (index, self.anchor @ view.T_world_second)):
            self.poses[k] = T
            self.frontend.set_pose(k, T)
        self.order = [first]
        for k in held:
            self._place(k)
        self.order.append(index)
        self.lost_run = 0

    def _place(self, index: int) -> None:
        prev = [self.poses[k] for k in self.order[-2:]]
        guess = constant_velocity(prev[1], prev[0]) if len(prev) == 2 else prev[-1]
        est = self.frontend.estimate(index, guess)
        if est is None:
            self.reports.append(f"frame {index}: no PnP pose ({self.frontend.status_line()})")
            self.poses[index] = guess
            self.frontend.set_pose(index, guess, trusted=False)
            self.lost_run += 1
        else:
            self.poses[index] = est.T_world_cam
            self.frontend.set_pose(index, est.T_world_cam)
            self.lost_run, self.depth = 0, est.median_depth
        self.order.append(index)

    def finish(self) -> None:
        """Frames still held when the log ended have no pose."""
        if self.held:
            self.reports.append(f"frames {self.held[0]}-{self.held[-1]}: the log ended before a two-view start")
