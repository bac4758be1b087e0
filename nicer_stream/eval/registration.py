"""Rigid + scale registration of a reconstructed surface onto the GT surface (trimmed ICP).

The paper aligns monocular meshes to the GT mesh with ICP (CloudCompare, Sec. 4
Metrics) rather than with the trajectory alignment: on a short clip, millimetres of
trajectory error move the Sim(3) scale by a percent, which shifts a 3 m room by
centimetres. Points are (N, 3) float64 metres; results map estimate points into the GT world.

Point-to-point with Umeyama steps, as CloudCompare's ICP with scale adjustment. A
point-to-plane variant was tried and rejected: on the known-pose Replica map (true
scale 1) it settled at scale 1.013, absorbing the reconstruction's surface offsets
into the scale; point-to-point gave 1.001. A GT surface that cannot pin all seven
degrees of freedom (one wall: sliding along it, or scaling about a point on it) is
not registered at all (`pins_similarity`).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from nicer_stream.eval.trajectory import Sim3, umeyama

ICP_MAX_POINTS = 50_000  # random subset of the estimate used for registration (speed)
ICP_DISTANCES_M = (0.20, 0.10, 0.05)  # trimming radius per stage, coarse to fine
ICP_ITERATIONS = 40  # per stage (point-to-point converges slowly along sliding directions)
MIN_CONSTRAINT_RATIO = 1e-3  # weakest / strongest direction of the point-to-plane information
# ICP that moves the trajectory's scale by more than this factor is not trusted: a poor mesh can
# shrink onto the GT (Replica, priors none: 1.18 -> 0.65). Good Replica maps moved by <= 3%.
MAX_SCALE_CHANGE = 1.1


def compose(a: Sim3, b: Sim3) -> Sim3:
    """a after b: x -> a(b(x))."""
    return Sim3(R=a.R @ b.R, t=a.scale * a.R @ b.t + a.t, scale=a.scale * b.scale)


def pins_similarity(points: np.ndarray, normals: np.ndarray, min_ratio: float = MIN_CONSTRAINT_RATIO) -> bool:
    """Whether a surface (points, unit normals: (N, 3)) constrains all of rotation,
    translation and scale: the 7x7 point-to-plane information matrix, with points
    centred and divided by their RMS radius, has no eigenvalue below `min_ratio` of the largest."""
    q = points - points.mean(0)
    q = q / max(float(np.sqrt((q * q).sum(1).mean())), 1e-12)
    J = np.concatenate([np.cross(q, normals), normals, (q * normals).sum(1, keepdims=True)], 1)
    ev = np.linalg.eigvalsh(J.T @ J)
    return bool(ev[-1] > 0 and ev[0] >= min_ratio * ev[-1])


def scale_change_trusted(init: Sim3, refined: Sim3, max_change: float = MAX_SCALE_CHANGE) -> bool:
    """Whether `refined` changes the scale of `init` by at most a factor `max_change` either way."""
    return abs(np.log(refined.scale / init.scale)) <= np.log(max_change)


def icp_sim3(src: np.ndarray, dst: np.ndarray, init: Sim3, seed: int = 0) -> Sim3:
    """Sim(3) with dst ~ s R src + t, refined from `init` by point-to-point ICP (ICP_* above).

    src: (N, 3) estimate surface samples (estimate world), dst: (M, 3) GT samples (GT world).
    Each iteration pairs every src point with its nearest dst point, keeps the pairs
    closer than the stage's distance (parts of one surface the other lacks do not
    pull) and solves Umeyama with scale on them. Returns `init` unchanged when fewer
    than 3 pairs survive, i.e. when the surfaces do not overlap.
    """
    src, dst = np.asarray(src, np.float64), np.asarray(dst, np.float64)
    if len(src) > ICP_MAX_POINTS:
        src = src[np.random.default_rng(seed).choice(len(src), ICP_MAX_POINTS, replace=False)]
    tree = cKDTree(dst)
    current = init
    for radius in ICP_DISTANCES_M:
        for _ in range(ICP_ITERATIONS):
            moved = current.apply_points(src)
            d, j = tree.query(moved, distance_upper_bound=radius, workers=-1)
            keep = np.isfinite(d)
            if keep.sum() < 3:
                return current
            step = umeyama(moved[keep], dst[j[keep]], with_scale=True)
            current = compose(step, current)
            if abs(step.scale - 1.0) < 1e-7 and np.linalg.norm(step.t) < 1e-6 and np.allclose(step.R, np.eye(3), atol=1e-7):
                break
    return current
