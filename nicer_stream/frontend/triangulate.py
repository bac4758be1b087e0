"""Two-view triangulation of pixel pairs with known camera poses (pure numpy)."""
from __future__ import annotations

import numpy as np

from nicer_stream.geometry.camera import project_world
from nicer_stream.types import Intrinsics


def triangulate(T_a: np.ndarray, T_b: np.ndarray, uv_a: np.ndarray, uv_b: np.ndarray, intr: Intrinsics,
                max_reproj_px: float = 2.0, min_parallax_deg: float = 1.0, with_angle: bool = False):
    """Linear (DLT) triangulation of N pixel pairs seen from T_world_cam `T_a` and `T_b`.

    Returns (world points (N, 3), ok (N,) bool): in front of both cameras, reprojecting
    within `max_reproj_px` in both, with rays at least `min_parallax_deg` apart (less
    parallax gives depths that noise dominates); `with_angle` adds their angles (N,) in degrees."""
    K = intr.matrix()
    P = [K @ np.linalg.inv(T)[:3] for T in (T_a, T_b)]
    n = len(uv_a)
    A = np.empty((n, 4, 4))
    for k, (Pk, uv) in enumerate(zip(P, (uv_a, uv_b))):
        A[:, 2 * k] = uv[:, :1] * Pk[2] - Pk[0]
        A[:, 2 * k + 1] = uv[:, 1:2] * Pk[2] - Pk[1]
    _, _, vt = np.linalg.svd(A)
    Xh = vt[:, -1]
    w = np.where(np.abs(Xh[:, 3]) < 1e-12, 1e-12, Xh[:, 3])
    X = Xh[:, :3] / w[:, None]
    ok = np.ones(n, bool)
    for T, uv in ((T_a, uv_a), (T_b, uv_b)):
        pr, z = project_world(T, X, intr)
        ok &= (z > 0) & (np.linalg.norm(pr - uv, axis=1) < max_reproj_px)
    ra, rb = X - T_a[:3, 3], X - T_b[:3, 3]
    cos = (ra * rb).sum(1) / np.maximum(np.linalg.norm(ra, axis=1) * np.linalg.norm(rb, axis=1), 1e-12)
    ok &= cos < np.cos(np.radians(min_parallax_deg))
    if with_angle:
        return X, ok, np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    return X, ok
