"""GT reference point cloud from GT depth frames (used when no GT mesh exists).

Each frame's GT z-depth is unprojected with its GT pose `T_world_cam`; normals
come from depth-image neighbours; the union is voxel-downsampled. Output is a
SurfaceSamples in the GT world, metres.
"""
from __future__ import annotations

import cv2
import numpy as np

from nicer_stream.eval.mesh import SurfaceSamples
from nicer_stream.geometry.depth_normals import unproject_depth
from nicer_stream.types import Intrinsics

DEFAULT_VOXEL_M = 0.02
MAX_POINTS_PER_FRAME = 200_000
DEPTH_MAX_SIDE = 400
"""GT depth is first downsampled (nearest) to this longer side: at 400 px a pixel
covers well under a 2 cm voxel up to ~5 m, and full-size frames cost ~1 s each."""


def normals_from_points(P: np.ndarray, depth: np.ndarray, max_rel_jump: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """Normals of a (H, W, 3) camera-frame point map from central differences.

    Returns ((H, W, 3) float64 unit normals facing the camera (n . p < 0), (H, W) bool valid).
    A pixel is invalid if it or a neighbour has no depth, or at a depth jump
    larger than `max_rel_jump` times its depth (object boundaries).
    """
    H, W = depth.shape
    n = np.zeros((H, W, 3))
    valid = np.zeros((H, W), dtype=bool)
    if H < 3 or W < 3:
        return n, valid
    dx = P[1:-1, 2:] - P[1:-1, :-2]
    dy = P[2:, 1:-1] - P[:-2, 1:-1]
    c = np.cross(dx, dy)
    norm = np.linalg.norm(c, axis=-1)
    d = depth
    centre = d[1:-1, 1:-1]
    nb = np.stack([d[1:-1, 2:], d[1:-1, :-2], d[2:, 1:-1], d[:-2, 1:-1]])
    ok = (centre > 0) & (nb > 0).all(0) & (norm > 0)
    ok &= (np.abs(nb - centre).max(0) <= max_rel_jump * centre)
    c = c / np.maximum(norm, 1e-30)[..., None]
    flip = (c * P[1:-1, 1:-1]).sum(-1) > 0
    c[flip] *= -1
    n[1:-1, 1:-1] = c
    valid[1:-1, 1:-1] = ok
    return n, valid


def voxel_downsample(s: SurfaceSamples, voxel: float) -> SurfaceSamples:
    """Average points (and renormalised normals) per cubic voxel of side `voxel` metres."""
    if len(s.points) == 0:
        return s
    keys = np.floor(s.points / voxel).astype(np.int64)
    keys -= keys.min(0)
    # One int64 per voxel (1D unique is ~50x faster than unique over rows).
    span = keys.max(0) + 1
    flat = (keys[:, 0] * span[1] + keys[:, 1]) * span[2] + keys[:, 2]
    _, inv, counts = np.unique(flat, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)

    def voxel_sum(x: np.ndarray) -> np.ndarray:  # (N, 3) -> (V, 3) per-voxel sums
        return np.stack([np.bincount(inv, x[:, i], minlength=len(counts)) for i in range(3)], 1)

    pts = voxel_sum(s.points) / counts[:, None]
    normals = None
    if s.normals is not None:
        normals = voxel_sum(s.normals)
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    return SurfaceSamples(pts, normals)


def shrink_depth(depth: np.ndarray, intr: Intrinsics, max_side: int = DEPTH_MAX_SIDE) -> tuple[np.ndarray, Intrinsics]:
    """Nearest-neighbour downsample of (H, W) depth so max(H, W) <= max_side, with matching intrinsics."""
    f = max_side / max(intr.width, intr.height)
    if f >= 1:
        return depth, intr
    small = intr.scaled(f)
    return cv2.resize(depth, (small.width, small.height), interpolation=cv2.INTER_NEAREST), small


def frame_points(depth: np.ndarray, intr: Intrinsics, T_world_cam: np.ndarray, voxel: float) -> SurfaceSamples:
    """World points and normals of one GT depth frame, voxel-downsampled."""
    depth, intr = shrink_depth(np.asarray(depth, np.float32), intr)
    P = unproject_depth(depth, intr)  # invalid pixels give z = 0
    n, valid = normals_from_points(P, np.asarray(depth, np.float64))
    idx = np.flatnonzero(valid)
    if len(idx) > MAX_POINTS_PER_FRAME:  # bound memory/time on large images
        idx = idx[:: int(np.ceil(len(idx) / MAX_POINTS_PER_FRAME))]
    R, t = T_world_cam[:3, :3], T_world_cam[:3, 3]
    pts = P.reshape(-1, 3)[idx] @ R.T + t
    nrm = n.reshape(-1, 3)[idx] @ R.T
    return voxel_downsample(SurfaceSamples(pts, nrm), voxel)


class ReferenceBuilder:
    """Accumulates GT depth frames one at a time (streaming) into a reference cloud."""

    def __init__(self, voxel: float = DEFAULT_VOXEL_M) -> None:
        self.voxel = voxel
        self._parts: list[SurfaceSamples] = []

    def add(self, depth: np.ndarray, intr: Intrinsics, T_world_cam: np.ndarray) -> None:
        """Add one frame: (H, W) GT z-depth, its intrinsics, (4, 4) GT T_world_cam."""
        self._parts.append(frame_points(depth, intr, np.asarray(T_world_cam, np.float64), self.voxel))

    def build(self) -> SurfaceSamples | None:
        """The voxel-downsampled union, or None when no valid depth was added."""
        parts = [p for p in self._parts if len(p.points)]
        if not parts:
            return None
        merged = SurfaceSamples(np.concatenate([p.points for p in parts]), np.concatenate([p.normals for p in parts]))
        return voxel_downsample(merged, self.voxel)
