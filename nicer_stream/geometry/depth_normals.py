"""Camera-frame surface normals from a depth image (pure numpy).

OpenCV camera axes (x right, y down, z forward); integer pixel coordinates are
pixel centres. Normals face the camera: n . p < 0 for the point p they belong to.
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from nicer_stream.types import Intrinsics


def unproject_depth(depth: np.ndarray, intr: Intrinsics) -> np.ndarray:
    """(H, W) z-depth -> (H, W, 3) float64 camera-frame points."""
    h, w = depth.shape
    u = (np.arange(w, dtype=np.float64) - intr.cx) / intr.fx
    v = (np.arange(h, dtype=np.float64) - intr.cy) / intr.fy
    z = depth.astype(np.float64)
    return np.stack([u[None, :] * z, v[:, None] * z, z], axis=-1)


def _tangent(points: np.ndarray, axis: int) -> np.ndarray:
    """(H, W, 3) one-sided difference along `axis`, taking the side whose depth changes least.

    Using the smoother side keeps normals next to depth discontinuities on
    their own surface instead of bridging foreground and background.
    """
    fwd = np.full_like(points, np.nan)
    bwd = np.full_like(points, np.nan)
    n = points.shape[axis]
    head = [slice(None)] * 3
    tail = [slice(None)] * 3
    head[axis], tail[axis] = slice(0, n - 1), slice(1, n)
    diff = points[tuple(tail)] - points[tuple(head)]
    fwd[tuple(head)] = diff
    bwd[tuple(tail)] = diff
    dz_f = np.abs(np.nan_to_num(fwd[..., 2], nan=np.inf))
    dz_b = np.abs(np.nan_to_num(bwd[..., 2], nan=np.inf))
    return np.where((dz_f <= dz_b)[..., None], np.nan_to_num(fwd), np.nan_to_num(bwd))


def view_rays(intr: Intrinsics) -> np.ndarray:
    """(H, W, 3) float64 unit camera-frame viewing directions through the pixel centres."""
    ray = unproject_depth(np.ones((intr.height, intr.width)), intr)
    return ray / np.linalg.norm(ray, axis=-1, keepdims=True)


def orient_towards_camera(normal: np.ndarray, intr: Intrinsics) -> np.ndarray:
    """(H, W, 3) normals -> float32 unit normals flipped where they face away (n . ray > 0).

    Zero-length normals become the reversed viewing ray.
    """
    ray = view_rays(intr)
    n = normal.astype(np.float64)
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    n = np.where(norm > 1e-12, n / np.maximum(norm, 1e-300), -ray)
    n[(n * ray).sum(-1) > 0] *= -1.0
    return n.astype(np.float32)


def fill_nearest(depth: np.ndarray) -> np.ndarray:
    """(H, W) depth with 0/non-finite pixels replaced by the nearest valid one -> float32.
    At least one pixel must be valid."""
    bad = ~(np.isfinite(depth) & (depth > 0))
    if not bad.any():
        return depth.astype(np.float32)
    idx = ndimage.distance_transform_edt(bad, return_distances=False, return_indices=True)
    return depth[idx[0], idx[1]].astype(np.float32)


def normals_from_depth(depth: np.ndarray, intr: Intrinsics) -> np.ndarray:
    """(H, W) z-depth (any positive scale, no invalid pixels) -> (H, W, 3) float32 unit normals.

    Normal = cross(dP/dv, dP/du) of neighbouring unprojected points, flipped to
    face the camera. Where that is degenerate (zero depth, collinear points)
    the normal is the reversed viewing ray. `intr` must match depth's size.
    """
    p = unproject_depth(depth, intr)
    return orient_towards_camera(np.cross(_tangent(p, 0), _tangent(p, 1)), intr)
