"""`--priors stereo`: each keyframe's depth and normal priors from plane-sweep stereo with its
neighbouring keyframes and the SLAM's own pose estimates (no ground truth, no weights).

The depth is in the poses' unit, so its scale and shift are fixed at (1, 0) (`stereo.scale =
'fixed'`): the map is pulled to the scale of its own trajectory, never to a per-frame fit. A
keyframe's prior is computed when a mapping call first includes it, from the keyframes nearest to it (one before and one
after where they exist), and once more when a later neighbour makes a one-sided pair
two-sided."""
from __future__ import annotations

import time

import cv2
import numpy as np
import torch

from nicer_stream.config import StereoConfig
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.model.bound import SceneBound
from nicer_stream.priors.normals_from_depth import fill_nearest, normals_from_depth
from nicer_stream.priors.stereo import sweep_depth


def partners_of(k: int, candidates: list[int], n: int = 2) -> tuple[int, ...]:
    """The `n` candidates nearest to `k` in index, one on each side first (k itself excluded)."""
    before = sorted((c for c in candidates if c < k), reverse=True)
    after = sorted(c for c in candidates if c > k)
    picked = before[:1] + after[:1]
    rest = sorted(before[1:] + after[1:], key=lambda c: abs(c - k))
    return tuple(sorted((picked + rest)[:n]))


def depth_range(T_world_cam: np.ndarray, bound: SceneBound, near_frac: float = 0.02) -> tuple[float, float]:
    """(near, far) z-depths to search: far reaches the bound's farthest corner from the camera."""
    lo, hi = bound.world_min_max()
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    far = float(np.linalg.norm(corners - T_world_cam[:3, 3], axis=1).max())
    return near_frac * far, far


def stereo_normals(depth: np.ndarray, intr) -> np.ndarray:
    """(H, W) depth with 0 where unknown -> (H, W, 3) camera normals, zero where unknown: from
    the depth median-filtered (stereo noise) with holes filled only for the differences."""
    smooth = cv2.medianBlur(depth.astype(np.float32), 5)
    valid = (depth > 0) & (smooth > 0)  # isolated pixels vanish in the median: unknown
    if not valid.any():
        return np.zeros(depth.shape + (3,), np.float32)
    n = normals_from_depth(fill_nearest(np.where(valid, smooth, 0.0)), intr)
    # A normal needs its neighbours known too.
    ok = cv2.erode(valid.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    return np.where(ok[..., None], n, 0.0).astype(np.float32)


class StereoPriors:
    """Fills `depth_prior`, `normal_prior` and `depth_scale_shift` of keyframes before mapping."""

    def __init__(self, params: StereoConfig = StereoConfig()) -> None:
        self.params = params
        self.used: dict[int, tuple[int, ...]] = {}  # keyframe -> partners its prior came from
        self.seconds = 0.0

    def update(self, window: list[int], frames: dict[int, MapFrame], poses: dict[int, torch.Tensor],
               keyframes: list[int], bound: SceneBound) -> list[int]:
        """Compute the priors the window's frames lack (or have one-sided); returns those updated."""
        t0 = time.perf_counter()
        candidates = [k for k in keyframes if k in frames and k in poses]
        done = []
        for k in window:
            if k not in frames or k not in poses:
                continue
            partners = partners_of(k, [c for c in candidates if c != k])
            if not partners or partners == self.used.get(k):
                continue
            old = self.used.get(k)
            two_sided = min(partners) < k < max(partners)
            if old is not None and (min(old) < k < max(old) or not two_sided):
                continue  # already two-sided, or no better now
            self._compute(frames[k], [frames[p] for p in partners], poses, bound)
            self.used[k] = partners
            done.append(k)
        self.seconds += time.perf_counter() - t0
        return done

    def _compute(self, f: MapFrame, partners: list[MapFrame], poses: dict[int, torch.Tensor], bound: SceneBound) -> None:
        T = poses[f.index].double().cpu().numpy()
        near, far = depth_range(T, bound)
        depth = sweep_depth(f.rgb.cpu().numpy(), T,
                               [(p.rgb.cpu().numpy(), poses[p.index].double().cpu().numpy()) for p in partners],
                               f.intr, near, far, self.params)
        f.depth_prior = torch.as_tensor(depth, device=f.rgb.device)
        f.normal_prior = torch.as_tensor(stereo_normals(depth, f.intr), device=f.rgb.device)
        f.depth_scale_shift = (1.0, 0.0) if self.params.scale == "fixed" else None
