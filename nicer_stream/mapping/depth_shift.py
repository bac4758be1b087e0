"""The shift of a relative depth prior, from its agreement with the normal prior.

A monocular depth prior is `w * depth + q` with unknown scale w and shift q. The
scale does not change the normals of the unprojected depth, but the shift bends
planes: the normals of `prior - q` agree best with the (independent) normal prior
when q is the true shift. The first SLAM mapping uses this to fix q before any
camera motion exists (the paper simply takes q = 0).
"""
from __future__ import annotations

import cv2
import numpy as np

from nicer_stream.geometry.depth_normals import normals_from_depth
from nicer_stream.types import Intrinsics

_BLUR_PX = 2.0  # prior depth noise makes per-pixel normals useless: smooth, then subsample
_STEP = 4


def normal_disagreement(depth: np.ndarray, normal: np.ndarray, intr: Intrinsics) -> float:
    """Mean (1 - cos) between normals of z-depth `depth` (H, W) > 0 and unit camera-frame
    `normal` (H, W, 3), both smoothed and subsampled by `_STEP`."""
    h, w = depth.shape
    size = (max(2, w // _STEP), max(2, h // _STEP))
    d = cv2.resize(cv2.GaussianBlur(depth.astype(np.float32), (0, 0), _BLUR_PX), size, interpolation=cv2.INTER_AREA)
    n = cv2.resize(normal.astype(np.float32), size, interpolation=cv2.INTER_AREA)
    nd = normals_from_depth(d, intr.resized(*size))
    cos = (nd * n).sum(-1) / np.linalg.norm(n, axis=-1).clip(1e-6)
    ok = np.isfinite(cos) & (d > 0)
    return float(np.mean(1.0 - cos[ok])) if ok.any() else float("inf")


def shift_from_normals(prior: np.ndarray, normal: np.ndarray, intr: Intrinsics, n_coarse: int = 29) -> float:
    """Shift q of relative depth `prior` (H, W; <= 0 or non-finite invalid) that best
    matches the normal prior (H, W, 3, camera frame): a coarse grid over
    [-median, 0.95 * 1st percentile], then a finer grid around the best value."""
    valid = np.isfinite(prior) & (prior > 0)
    if valid.mean() < 0.5:
        return 0.0
    filled = np.where(valid, prior, np.median(prior[valid])).astype(np.float64)
    lo, hi = -float(np.median(filled)), 0.95 * float(np.percentile(filled, 1))

    def cost(q: float) -> float:
        return normal_disagreement(filled - q, normal, intr)

    grid = np.linspace(lo, hi, n_coarse)
    best = int(np.argmin([cost(q) for q in grid]))
    step = grid[1] - grid[0]
    fine = np.linspace(max(lo, grid[best] - step), min(hi, grid[best] + step), 11)
    return float(fine[int(np.argmin([cost(q) for q in fine]))])
