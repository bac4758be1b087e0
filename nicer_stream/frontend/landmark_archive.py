"""Landmarks that left the frontend's window, kept to be recognised when the camera looks back.

A track lives while consecutive frames match it; a place seen again after the track was lost
starts new tracks, new landmarks triangulated from the drifted poses of now, and the scale drifts
a little more with every return (a camera panning back and forth over one desk). Each archived
landmark keeps its world point, its latest SIFT descriptor, the parallax it was triangulated with,
and its latest observation by a trusted frame (that frame's pose and pixel): recognised again, it
returns with that observation, which the bundle adjustment holds as a fixed camera (as it holds
every landmark's latest observation by a frame that left the window), pulling the new poses
towards the old ones instead of moving the old point (the sliding-window BA of ORB-SLAM's
local mapping, where keyframes outside the window stay fixed)."""
from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from nicer_stream.geometry.camera import project_world
from nicer_stream.types import Intrinsics


def scaled_pose(T_world_cam: np.ndarray, centre: np.ndarray, factor: float) -> np.ndarray:
    """A copy of T_world_cam (4, 4) with its camera centre scaled by `factor` about world point `centre` (3,)."""
    T = T_world_cam.copy()
    T[:3, 3] = centre + factor * (T[:3, 3] - centre)
    return T


@dataclass(frozen=True)
class Anchor:
    """A trusted frame's observation of a landmark: T_world_cam (4, 4) float64 and pixel (2,)."""

    T_world_cam: np.ndarray
    uv: np.ndarray


@dataclass(frozen=True)
class ArchivedLandmark:
    """World point (3,), latest descriptor (128,) float32, triangulation parallax in degrees, the
    latest trusted observation (None when no trusted frame saw it) and the frame it was archived at."""

    point: np.ndarray
    descriptor: np.ndarray
    parallax_deg: float
    anchor: Anchor | None
    frame: int


class LandmarkArchive:
    """At most `capacity` landmarks by track id, the oldest archived dropped first."""

    def __init__(self, capacity: int) -> None:
        self.capacity = capacity
        self.items: OrderedDict[int, ArchivedLandmark] = OrderedDict()

    def __len__(self) -> int:
        return len(self.items)

    def add(self, track: int, item: ArchivedLandmark) -> None:
        self.items[track] = item
        self.items.move_to_end(track)
        while len(self.items) > self.capacity:
            self.items.popitem(last=False)

    def forget_before(self, frame: int) -> None:
        """Drop the landmarks archived before `frame`."""
        while self.items and next(iter(self.items.values())).frame < frame:
            self.items.popitem(last=False)

    def pop(self, track: int) -> ArchivedLandmark:
        return self.items.pop(track)

    def clear(self) -> None:
        self.items.clear()

    def rescale(self, centre: np.ndarray, factor: float) -> None:
        """Scale the points and anchor camera centres by `factor` about world point `centre` (3,)."""
        for t, a in self.items.items():
            anchor = None if a.anchor is None else Anchor(scaled_pose(a.anchor.T_world_cam, centre, factor), a.anchor.uv)
            self.items[t] = ArchivedLandmark(centre + factor * (a.point - centre), a.descriptor, a.parallax_deg,
                                             anchor, a.frame)

    def in_view(self, T_world_cam: np.ndarray, intr: Intrinsics, margin_px: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The landmarks in front of the camera at `T_world_cam` projecting within `margin_px` of
        the image: (track ids (T,), pixels (T, 2), descriptors (T, 128) float32)."""
        if not self.items:
            return np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros((0, 128), np.float32)
        tracks = np.fromiter(self.items, np.int64, len(self.items))
        px, z = project_world(T_world_cam, np.stack([a.point for a in self.items.values()]), intr)
        size = np.array([intr.width, intr.height])
        near = (z > 0) & np.all((px >= -margin_px) & (px < size + margin_px), axis=1)
        lib = np.stack([self.items[t].descriptor for t in tracks[near].tolist()]).astype(np.float32) if near.any() \
            else np.zeros((0, 128), np.float32)
        return tracks[near], px[near], lib

    def match(self, T_world_cam: np.ndarray, intr: Intrinsics, uv: np.ndarray, desc: np.ndarray,
              radius_px: float, ratio: float) -> tuple[np.ndarray, np.ndarray]:
        """Keypoints (pixels uv (Q, 2), descriptors (Q, 128) float32) recognised as archived
        landmarks seen from `T_world_cam`: each keypoint's nearest descriptor among the landmarks
        that project within `radius_px` of it, kept when it passes the ratio test against the
        second nearest (or is alone within the radius and as close as the ratio-tested matches'
        90th percentile), one keypoint per landmark. Returns (keypoint rows (K,), track ids (K,)).
        Only pairs within the radius are compared (a k-d tree over the projections): the archive
        holds thousands of landmarks, a frame a thousand keypoints."""
        empty = np.zeros(0, np.int64), np.zeros(0, np.int64)
        tracks, px, lib = self.in_view(T_world_cam, intr, radius_px)
        if len(tracks) < 2 or not len(uv):
            return empty
        within = cKDTree(px).query_ball_point(uv, radius_px)
        q = np.repeat(np.arange(len(uv)), [len(w) for w in within])
        if not len(q):
            return empty
        j = np.concatenate([np.asarray(w, np.int64) for w in within])
        d = np.linalg.norm(desc.astype(np.float32)[q] - lib[j], axis=1)
        order = np.lexsort((d, q))  # by keypoint, nearest first
        q, j, d = q[order], j[order], d[order]
        first = np.r_[True, q[1:] != q[:-1]]
        lead = np.flatnonzero(first)
        has_second = np.r_[lead[1:], len(q)] - lead >= 2
        second_d = np.where(has_second, d[np.minimum(lead + 1, len(d) - 1)], np.inf)
        good = has_second & (d[lead] < ratio * second_d)
        if not good.any():
            return empty
        bar = np.percentile(d[lead][good], 90)
        keep = good | (~has_second & (d[lead] <= bar))
        lead = lead[keep]
        rows, used = [], set()
        for k in lead[np.argsort(d[lead], kind="stable")]:  # one keypoint per landmark: the closest
            if j[k] not in used:
                used.add(j[k])
                rows.append((q[k], tracks[j[k]]))
        out = np.array(rows, np.int64).T
        return out[0], out[1]
