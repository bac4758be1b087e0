"""Camera poses from pixel matches with OpenCV (numpy float64): a second view's relative pose by
the essential matrix, a camera's pose from 2D-3D matches by PnP. Shared by the classical frontend,
the two-view start and the flow-based tracking start."""
from __future__ import annotations

import cv2
import numpy as np
import torch

from nicer_stream.geometry.camera import camera_dirs
from nicer_stream.types import Intrinsics


def essential_pose(uv0: np.ndarray, uv1: np.ndarray, intr: Intrinsics, thresh_px: float,
                   min_inliers: int) -> tuple[np.ndarray, int, np.ndarray] | None:
    """T_world_cam (4, 4) float64 of a second view with the first at the identity and a unit
    baseline, from pixel matches uv0 -> uv1 (N, 2) by the essential matrix (RANSAC at
    `thresh_px`); with the inlier count and the (N,) bool inlier mask. None with fewer than
    `min_inliers` inliers or when the matches do not move (no essential matrix exists)."""
    n0 = camera_dirs(torch.from_numpy(uv0), intr)[:, :2].numpy()  # normalised image coordinates
    n1 = camera_dirs(torch.from_numpy(uv1), intr)[:, :2].numpy()
    try:
        E, mask = cv2.findEssentialMat(n0, n1, np.eye(3), cv2.RANSAC, 0.999, thresh_px / intr.fx)
    except cv2.error:  # identical points (a camera at rest): OpenCV's 5-point solver asserts
        return None
    if E is None or E.shape != (3, 3):
        return None
    n_in, R, t, mask = cv2.recoverPose(E, n0, n1, np.eye(3), mask=mask)
    if n_in < min_inliers:
        return None
    T_second_first = np.eye(4)
    T_second_first[:3, :3], T_second_first[:3, 3] = R, t[:, 0]
    return np.linalg.inv(T_second_first), int(n_in), mask[:, 0] > 0


def pnp_pose(points_world: np.ndarray, uv: np.ndarray, intr: Intrinsics, T_guess: np.ndarray,
             reproj_px: float = 2.0, min_inliers: int = 30) -> tuple[np.ndarray, int] | None:
    """T_world_cam (4, 4) float64 of a camera seeing `points_world` (N, 3) at pixels `uv`
    (N, 2), by RANSAC PnP started at `T_guess` and refined on the inliers; with its inlier
    count. None with fewer than `min_inliers` inliers."""
    if len(points_world) < min_inliers:
        return None
    K = intr.matrix()
    T_cw = np.linalg.inv(T_guess)
    rvec, _ = cv2.Rodrigues(T_cw[:3, :3])
    tvec = T_cw[:3, 3].copy()
    X, x = points_world.astype(np.float64), uv.astype(np.float64)
    ok, rvec, tvec, inl = cv2.solvePnPRansac(X, x, K, None, rvec, tvec.reshape(3, 1), useExtrinsicGuess=True,
                                             iterationsCount=200, reprojectionError=reproj_px, confidence=0.999,
                                             flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok or inl is None or len(inl) < min_inliers:
        return None
    inl = inl[:, 0]
    rvec, tvec = cv2.solvePnPRefineLM(X[inl], x[inl], K, None, rvec, tvec)
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(rvec)[0]
    T[:3, 3] = tvec[:, 0]
    return np.linalg.inv(T), len(inl)
