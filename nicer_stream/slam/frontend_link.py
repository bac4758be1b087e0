"""The classical frontend as the SLAM uses it: every call timed, its poses passed through its own
health checks (`frontend/health.py`), told the pose the SLAM settles on for each frame. Without a
frontend every call is a no-op that returns nothing."""
from __future__ import annotations

import logging
import time
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
import torch

from nicer_stream.frontend.frontend import ClassicalFrontend, FrontendPose, TwoViewTracks
from nicer_stream.config import RenderConfig
from nicer_stream.frontend.health import FrontendHealth
from nicer_stream.render.renderer import depth_at_pixels
from nicer_stream.slam.events import TrackingWarning
from nicer_stream.slam.state import SlamState
from nicer_stream.types import Frame, Intrinsics

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FrontendSeed:
    """The frontend's pose of a frame that passed the health checks, and the landmarks it saw:
    `pixels` (M, 2) and world `points` (M, 3)."""

    pose: FrontendPose
    pixels: np.ndarray
    points: np.ndarray


class FrontendLink:
    def __init__(self, frontend: ClassicalFrontend | None, state: SlamState) -> None:
        self.frontend, self.state = frontend, state
        self.seconds = 0.0  # spent in the frontend
        self.health = FrontendHealth()  # the frontend's own checks of its poses
        self.distrusted: set[int] = set()  # frames whose frontend pose failed them
        self.scene_depth: float | None = None  # the latest checked pose's median landmark depth
        self.scale_off_map: list[tuple[int, float]] = []  # (frame, ratio) where its scale left the map's

    @property
    def intr(self) -> Intrinsics | None:
        """The intrinsics of the image the frontend tracks in (None without a frontend)."""
        return self.frontend.intr if self.frontend is not None else None

    @contextmanager
    def timer(self):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.seconds += time.perf_counter() - t0

    def observe(self, frame: Frame) -> None:
        """Track features into `frame`: the source's larger image when it has one (`frontend.max_side`)."""
        if self.frontend is None:
            return
        with self.timer():
            if frame.detail is not None:
                self.frontend.observe(frame.index, frame.detail.grey, frame.detail.intrinsics)
            else:
                self.frontend.observe(frame.index, frame.rgb, frame.intrinsics)

    def estimate(self, index: int, T_guess: torch.Tensor) -> FrontendSeed | None:
        """The frontend's pose of `index`, or None when it has none or its health check fails
        (the frame is then tracked against the map from the motion model)."""
        if self.frontend is None:
            return None
        with self.timer():
            front = self.frontend.estimate(index, T_guess.double().cpu().numpy())
            ids, uv = self.frontend.obs[index]
            luv, X = self.frontend.landmark_observations(index)
            reports = self.health.check(index, None if front is None else front.T_world_cam, ids, uv, luv, X,
                                        self.frontend.intr, None if front is None else front.median_depth)
        for r in reports:
            log.warning("%s", r)
            self.state.warnings.append(TrackingWarning(r.index, f"frontend {r.kind}", r.message))
        if front is not None and any(r.kind != "lost" for r in reports):
            self.distrusted.add(index)
            return None
        if front is None:
            return None
        self.scene_depth = front.median_depth
        return FrontendSeed(front, luv, X)

    def set_pose(self, index: int, T: torch.Tensor, trusted: bool) -> None:
        """The pose the SLAM settled on for `index`; a frame whose own pose failed adopts it."""
        if self.frontend is not None:
            with self.timer():
                self.frontend.set_pose(index, T.double().cpu().numpy(), trusted, adopt=index in self.distrusted)

    def seed_from_map(self, index: int, view: tuple, render: RenderConfig, check_scale: bool) -> None:
        """Landmarks from the map `view` ((model, beta), `map_view()`) for trusted frame `index`'s
        tracks that have none, when it sees few; with `check_scale` (a keyframe) its scale against
        the map's is checked in any case (`ClassicalFrontend.seed_landmarks`)."""
        if self.frontend is None or self.frontend.cfg.map_landmarks_below <= 0:
            return
        model, beta = view
        cfg = self.frontend.cfg
        with self.timer():
            n, ratio = self.frontend.seed_landmarks(index, lambda T, uv: depth_at_pixels(
                model, beta, render, T, self.frontend.intr, uv, cfg.map_landmark_opacity, cfg.map_landmark_samples),
                check_scale)
        if self.frontend.off_map_scale(ratio):
            log.warning("frame %d: the frontend's landmarks are %.2fx the map's depth: %s", index, ratio,
                        "frontend rescaled to the map" if cfg.map_rescale else "no landmarks from the map")
            self.scale_off_map.append((index, ratio))
        if n:
            log.info("frame %d: %d landmarks from the map's depth", index, n)

    def two_view(self, first: int, index: int, median_m: float, fallback: bool = False) -> TwoViewTracks | None:
        if self.frontend is None:
            return None
        with self.timer():
            return self.frontend.two_view(first, index, median_m, fallback=fallback)

    def pin(self, indices: set[int]) -> None:
        """Frames whose observations outlive the frontend's window (the held first view of a start
        still waiting for its second)."""
        if self.frontend is not None:
            self.frontend.pinned = indices

    def landmarks(self) -> np.ndarray | None:
        """The landmarks (P, 3), world frame, or None without any."""
        if self.frontend is None or not self.frontend.landmarks:
            return None
        return np.stack(list(self.frontend.landmarks.values()))

    def view_landmarks(self, index: int) -> np.ndarray | None:
        """The world points (M, 3) of frame `index`'s landmarks, or None."""
        if self.frontend is None or index not in self.frontend.obs:
            return None
        X = self.frontend.landmark_observations(index)[1]
        return X if len(X) else None

    def placed(self):
        """The frames the frontend has posed itself (None without a frontend)."""
        return self.frontend.placed() if self.frontend is not None else None
