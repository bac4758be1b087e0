"""Corner detection and pyramidal Lucas-Kanade tracking (OpenCV), with a forward-backward check."""
from __future__ import annotations

import cv2
import numpy as np


def detect_corners(grey: np.ndarray, n: int, min_distance: float, avoid: np.ndarray | None = None) -> np.ndarray:
    """Up to `n` Shi-Tomasi corners (M, 2) float32 (u, v), at least `min_distance` pixels
    from each other and from the points `avoid` (K, 2)."""
    if n <= 0:
        return np.zeros((0, 2), np.float32)
    mask = np.full(grey.shape, 255, np.uint8)
    if avoid is not None:
        for u, v in np.round(avoid).astype(int):
            cv2.circle(mask, (int(u), int(v)), int(min_distance), 0, -1)
    pts = cv2.goodFeaturesToTrack(grey, n, 0.01, min_distance, mask=mask, blockSize=5)
    return np.zeros((0, 2), np.float32) if pts is None else pts[:, 0].astype(np.float32)


def track(prev: np.ndarray, cur: np.ndarray, pts: np.ndarray, fb_px: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Track `pts` (N, 2) from image `prev` into `cur`: (new positions (N, 2) float32, ok (N,)
    bool). A point is kept when tracking back lands within `fb_px` of where it started and
    it stays inside the image."""
    if len(pts) == 0:
        return pts.reshape(0, 2), np.zeros(0, bool)
    p0 = pts.reshape(-1, 1, 2).astype(np.float32)
    lk = dict(winSize=(21, 21), maxLevel=3, criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01))
    p1, st1, _ = cv2.calcOpticalFlowPyrLK(prev, cur, p0, None, **lk)
    p0b, st2, _ = cv2.calcOpticalFlowPyrLK(cur, prev, p1, None, **lk)
    h, w = cur.shape
    p1 = p1[:, 0]
    ok = (st1[:, 0] == 1) & (st2[:, 0] == 1) & (np.linalg.norm(p0b[:, 0] - p0[:, 0], axis=1) < fb_px)
    ok &= (p1[:, 0] >= 0) & (p1[:, 0] <= w - 1) & (p1[:, 1] >= 0) & (p1[:, 1] <= h - 1)
    return p1, ok


class KltTracks:
    """Track ids and pixels through the frames: Shi-Tomasi corners followed by pyramidal LK,
    topped up with new corners each frame. Call `step` on every frame in input order."""

    def __init__(self, corners: int, min_distance_px: float, fb_px: float) -> None:
        self.corners, self.min_distance_px, self.fb_px = corners, min_distance_px, fb_px
        self.prev: np.ndarray | None = None
        self.ids = np.zeros(0, np.int64)
        self.uv = np.zeros((0, 2), np.float32)
        self.next_id = 0

    def step(self, grey: np.ndarray, predicted=None, radius_px: float = 0.0, min_guided: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """(H, W) uint8 -> (track ids (M,) int64, pixels (M, 2) float64) of this frame.
        `predicted`, `radius_px` and `min_guided` (see `SiftTracks.step`) are ignored: LK searches locally."""
        if self.prev is not None and self.prev.shape == grey.shape:
            uv, ok = track(self.prev, grey, self.uv, self.fb_px)
            self.ids, self.uv = self.ids[ok], uv[ok]
        else:
            self.ids, self.uv = np.zeros(0, np.int64), np.zeros((0, 2), np.float32)
        new = detect_corners(grey, self.corners - len(self.ids), self.min_distance_px, self.uv)
        self.ids = np.concatenate([self.ids, np.arange(self.next_id, self.next_id + len(new))])
        self.uv = np.concatenate([self.uv, new])
        self.next_id += len(new)
        self.prev = grey
        return self.ids.copy(), self.uv.astype(np.float64)
