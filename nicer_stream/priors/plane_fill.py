"""Fill large untextured holes of a stereo depth with the plane their rim lies on.

Window matching finds nothing on a blank wall or ceiling, and those are the largest surfaces of
a room: left without a depth prior, the map guesses them from colour alone (the Replica clip's
white wall: 20-30 cm off). Such a hole is bounded by the walls it belongs to: the known depths
on the hole's rim, back-projected, fit up to `max_planes` planes (sequential RANSAC), and each
hole pixel takes the nearest of them along its ray. Seen from inside a room, every visible
point lies on the camera's side of every wall plane, so a plane that a share of the rim lies
behind is not a wall bounding the hole (it is a foreground surface) and is not used; two walls
meeting in a corner are both kept, and the nearer one is the visible one. A rim that these
planes do not explain (a hole between a foreground object and the wall behind it, a curved
surface) is left unfilled.
"""
from __future__ import annotations

import cv2
import numpy as np
import torch

from nicer_stream.geometry.camera import camera_dirs, pixel_grid
from nicer_stream.types import Intrinsics


def fit_wall_planes(points: np.ndarray, tol: float, rng: np.random.Generator, max_planes: int = 3,
                    min_share: float = 0.2, max_behind: float = 0.1, tries: int = 128) -> tuple[list[tuple[np.ndarray, float]], float]:
    """Sequential RANSAC over (N, 3) camera points (the camera at the origin): up to `max_planes`
    planes (unit n (3,), c > 0) with n.x = c, each taking at least `min_share` of the points as
    new inliers (within `tol` times a point's z) and with at most `max_behind` of all points beyond
    it (n.x - c > tol z: behind the plane, seen from the camera). Returns the planes and the share
    of the points on one of them."""
    z = points[:, 2]
    free = np.ones(len(points), bool)
    planes: list[tuple[np.ndarray, float]] = []

    def orient(n, c):  # the camera's side of the plane is n.x < c
        return (-n, -c) if c < 0 else (n, c)

    def rel_dist(planes):  # (len(planes), N): each point's distance to each plane over its z
        return np.stack([np.abs(points @ n - c) / z for n, c in planes])

    for _ in range(max_planes):
        idx = np.flatnonzero(free)
        if len(idx) < 3:
            break
        best, best_count = None, 0
        for _ in range(tries):
            a, b, c = points[rng.choice(idx, 3, replace=False)]
            n = np.cross(b - a, c - a)
            norm = np.linalg.norm(n)
            if norm < 1e-12:
                continue
            n, off = orient(n / norm, float(n @ a) / norm)
            dist = points @ n - off
            if (dist > tol * z).mean() > max_behind:
                continue
            count = int(((np.abs(dist) <= tol * z) & free).sum())
            if count > best_count:
                best, best_count = (n, off), count
        if best is None or best_count < min_share * len(points):
            break
        planes.append(best)
        free &= rel_dist([best])[0] > tol
    if not planes:
        return planes, 0.0
    # Least squares on each plane's points, a point going to the plane it lies nearest (two walls'
    # points near their corner are within `tol` of both); a refit that puts points behind stays out.
    for _ in range(2):
        dist = rel_dist(planes)
        owner = np.where(dist.min(0) <= tol, dist.argmin(0), -1)
        for k in range(len(planes)):
            mine = points[owner == k]
            if len(mine) < 3:
                continue
            centre = mine.mean(0)
            m = np.linalg.svd(mine - centre, full_matrices=False)[2][-1]
            m, d = orient(m, float(m @ centre))
            if ((points @ m - d) > tol * z).mean() <= max_behind:
                planes[k] = (m, d)
    return planes, float((rel_dist(planes).min(0) <= tol).mean())


def fill_planar_holes(depth: np.ndarray, intr: Intrinsics, blank: np.ndarray | None = None, min_area: float = 0.01,
                      rim: int = 4, tol: float = 0.03, min_inliers: float = 0.7, max_planes: int = 1,
                      min_share: float = 0.2, max_behind: float = 0.1, seed: int = 0) -> np.ndarray:
    """(H, W) z-depth with 0 where unknown -> the same with each hole (connected unknown region
    wider than 2 `rim` + 1 pixels, of at least `min_area` of the image) filled from the walls its
    rim lies on: the known pixels within `rim` pixels of the hole, back-projected, fit up to
    `max_planes` planes (`fit_wall_planes`: inliers within `tol` of the depth, each at least
    `min_share` of the rim, at most `max_behind` of the rim behind it) that hold at least
    `min_inliers` of the rim together; a hole pixel takes the nearest plane in front of the camera
    along its ray (left unknown where none is, or beyond twice the rim's farthest depth).
    `blank` (H, W) bool marks untextured pixels: then only holes mostly (half or more) blank are
    filled. Why: holes left by occlusions or disagreeing partners are textured, and their rim
    often is one plane while the hole holds another surface (the synthetic room's gaps between
    objects: 11-24% depth error once filled; Replica's blank walls: 0.2-1.2%)."""
    known = depth > 0
    if known.all() or not known.any():
        return depth
    # Thin unknown strips (depth edges the sweep dropped) would join every hole into one: only
    # the unknown regions wider than the rim are holes.
    kernel = np.ones((2 * rim + 1, 2 * rim + 1), np.uint8)
    wide = cv2.morphologyEx((~known).astype(np.uint8), cv2.MORPH_OPEN, kernel)
    count, labels = cv2.connectedComponents(wide, connectivity=4)
    # (H, W, 3) rays with z = 1: z-depth times a ray is the point.
    rays = camera_dirs(pixel_grid(intr, dtype=torch.float64), intr).numpy().reshape(intr.height, intr.width, 3)
    rng = np.random.default_rng(seed)
    out = depth.copy()
    for label in range(1, count):
        hole = labels == label
        if hole.mean() < min_area or (blank is not None and blank[hole].mean() < 0.5):
            continue
        ring = cv2.dilate(hole.astype(np.uint8), kernel).astype(bool) & known
        if ring.sum() < 30:
            continue
        planes, share = fit_wall_planes(rays[ring] * depth[ring][:, None], tol, rng, max_planes, min_share, max_behind)
        if not planes or share < min_inliers:
            continue
        hole_rays = rays[hole]
        z = np.full(len(hole_rays), np.inf)
        for n, c in planes:  # c > 0: a ray meets the plane in front of the camera where n . ray > 0
            along = hole_rays @ n
            z = np.minimum(z, np.where(along > 1e-9, c / np.maximum(along, 1e-9), np.inf))
        z[~np.isfinite(z) | (z > 2.0 * float(depth[ring].max()))] = 0.0
        out[hole] = z
    return out.astype(np.float32)
