"""Mesh metrics: accuracy, completion, completion ratio, normal consistency; GT culling.

All points are (N, 3) float64 world coordinates in metres (the GT world: the
estimate is Sim(3)-aligned before it gets here); normals are (N, 3) unit vectors.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
import trimesh
from scipy.spatial import cKDTree

from nicer_stream.geometry.camera import in_image, project
from nicer_stream.geometry.se3 import invert, transform_points
from nicer_stream.io.output_dir import MeshReport
from nicer_stream.types import Intrinsics

COMPLETION_THRESHOLD_M = 0.05


@dataclass(frozen=True)
class SurfaceSamples:
    """Points on a surface: `points` (N, 3) float64 metres, `normals` (N, 3) unit or None."""

    points: np.ndarray
    normals: np.ndarray | None = None

    def subset(self, mask: np.ndarray) -> "SurfaceSamples":
        """The samples where the (N,) bool `mask` is True."""
        return SurfaceSamples(self.points[mask], None if self.normals is None else self.normals[mask])


def sample_mesh(mesh: trimesh.Trimesh, n: int = 200_000, seed: int = 0) -> SurfaceSamples:
    """`n` area-uniform random samples on the mesh surface with their face normals."""
    if len(mesh.faces) == 0:
        raise ValueError("cannot sample a mesh without faces")
    pts, face = trimesh.sample.sample_surface(mesh, n, seed=seed)
    return SurfaceSamples(np.asarray(pts, np.float64), np.asarray(mesh.face_normals[face], np.float64))


def mesh_metrics(est: SurfaceSamples, gt: SurfaceSamples, threshold: float = COMPLETION_THRESHOLD_M
                 ) -> MeshReport:
    """Accuracy / completion / completion ratio / normal consistency of `est` against `gt` (no `reference`):
    acc_m: mean distance estimate -> GT; comp_m: mean GT -> estimate (metres); comp_ratio: fraction
    in [0, 1] of GT samples closer than the threshold to the estimate; normal_consistency: mean
    |n_est . n_gt| of nearest neighbours, both directions (None without normals)."""
    if len(est.points) == 0 or len(gt.points) == 0:
        raise ValueError("mesh metrics need non-empty estimate and reference samples")
    d_est, i_est = cKDTree(gt.points).query(est.points, workers=-1)  # est -> nearest GT
    d_gt, i_gt = cKDTree(est.points).query(gt.points, workers=-1)  # GT -> nearest est
    nc = None
    if est.normals is not None and gt.normals is not None:
        # Absolute dot: mesh orientation (inside/outside) is not what is measured here.
        nc_acc = np.abs((est.normals * gt.normals[i_est]).sum(1)).mean()
        nc_comp = np.abs((gt.normals * est.normals[i_gt]).sum(1)).mean()
        nc = float(0.5 * (nc_acc + nc_comp))
    return MeshReport(
        acc_m=float(d_est.mean()),
        comp_m=float(d_gt.mean()),
        comp_ratio=float((d_gt < threshold).mean()),
        normal_consistency=nc,
    )


@dataclass(frozen=True)
class CullCamera:
    """A GT camera used to decide which GT surface was observed.

    T_world_cam: (4, 4) float64 camera-to-world; depth: (H, W) float32 z-depth of
    `intrinsics`' size (0 = invalid), or None to skip the occlusion test.
    """

    T_world_cam: np.ndarray
    intrinsics: Intrinsics
    depth: np.ndarray | None = None


def visible_in(points: np.ndarray, cam: CullCamera, depth_tol: float, near: float = 1e-3) -> np.ndarray:
    """(N,) bool: in front of `cam`, inside its image, and not behind its GT depth by more than depth_tol."""
    T_cam_world = invert(torch.from_numpy(np.asarray(cam.T_world_cam, np.float64)))
    p_cam = transform_points(T_cam_world, torch.from_numpy(points))
    uv, z = project(p_cam, cam.intrinsics)
    ok = (z > near) & in_image(uv, cam.intrinsics)
    if cam.depth is None:
        return ok.numpy()
    ok = ok.numpy()
    u = np.clip(np.rint(uv[:, 0].numpy()), 0, cam.intrinsics.width - 1).astype(np.int64)
    v = np.clip(np.rint(uv[:, 1].numpy()), 0, cam.intrinsics.height - 1).astype(np.int64)
    d = cam.depth[v, u]
    # Invalid GT depth (0) means this camera saw nothing there: not observed.
    return ok & (d > 0) & (z.numpy() <= d + depth_tol)


def cull_observed(points: np.ndarray, cameras: list[CullCamera], depth_tol: float = 0.05) -> np.ndarray:
    """(N,) bool mask of GT points observed by at least one camera (frustum + occlusion)."""
    points = np.asarray(points, np.float64)
    keep = np.zeros(len(points), dtype=bool)
    for cam in cameras:
        todo = ~keep
        if not todo.any():
            break
        keep[todo] = visible_in(points[todo], cam, depth_tol)
    return keep
