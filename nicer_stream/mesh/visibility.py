"""Cull a mesh to what rendered depth maps say the cameras actually see."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from nicer_stream.types import Intrinsics


@dataclass(frozen=True)
class DepthView:
    """A camera T_world_cam (4, 4) with intrinsics and a z-depth map (H, W) in metres (0 = none)."""

    T_world_cam: np.ndarray
    intr: Intrinsics
    depth: np.ndarray


def visible_vertices(vertices: np.ndarray, views: list[DepthView], margin: float, near: float = 0.05) -> np.ndarray:
    """(V,) bool: vertex (V, 3) world lies inside some view's image, in front of it and no
    more than `margin` metres behind that view's depth at its pixel."""
    seen = np.zeros(len(vertices), dtype=bool)
    for v in views:
        R, t = v.T_world_cam[:3, :3], v.T_world_cam[:3, 3]
        p = (vertices - t) @ R  # world -> camera: R^T (x - t)
        z = p[:, 2]
        zs = np.maximum(z, 1e-9)
        u = np.rint(v.intr.fx * p[:, 0] / zs + v.intr.cx).astype(np.int64)
        w = np.rint(v.intr.fy * p[:, 1] / zs + v.intr.cy).astype(np.int64)
        inside = (z > near) & (u >= 0) & (u < v.intr.width) & (w >= 0) & (w < v.intr.height)
        d = np.zeros(len(vertices))
        d[inside] = v.depth[w[inside], u[inside]]
        seen |= inside & (d > 0) & (z <= d + margin)
    return seen


def cull_occluded(mesh: trimesh.Trimesh, views: list[DepthView], margin: float = 0.1) -> trimesh.Trimesh:
    """Copy of `mesh` keeping faces with at least one visible vertex (see `visible_vertices`)."""
    if len(mesh.faces) == 0 or not views:
        return mesh.copy()
    seen = visible_vertices(np.asarray(mesh.vertices), views, margin)
    keep = seen[np.asarray(mesh.faces)].any(axis=1)
    out = mesh.copy()
    out.update_faces(keep)
    out.remove_unreferenced_vertices()
    return out
