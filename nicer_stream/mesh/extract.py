"""Mesh extraction from an SDF by marching cubes, and culling to camera frustums.

All coordinates are world coordinates in metres (or whatever frame sdf_fn
takes); poses are T_world_cam (camera-to-world, OpenCV axes).
"""
from __future__ import annotations

from typing import Callable

import numpy as np
import torch
import trimesh
from skimage.measure import marching_cubes

from nicer_stream.errors import UserError
from nicer_stream.geometry.camera import in_image, project
from nicer_stream.geometry.se3 import invert, transform_points
from nicer_stream.types import Intrinsics

SdfFn = Callable[[torch.Tensor], torch.Tensor]
ColorFn = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]


def _grid_axes(bound_min, bound_max, resolution: int) -> list[np.ndarray]:
    """Three (resolution,) float64 arrays of sample coordinates, ends included."""
    lo = np.asarray(bound_min, dtype=np.float64).reshape(3)
    hi = np.asarray(bound_max, dtype=np.float64).reshape(3)
    if resolution < 2:
        raise UserError(f"mesh resolution must be at least 2 (got {resolution}): pass a larger resolution")
    if not np.all(hi > lo):
        raise UserError(f"mesh bound_max {hi.tolist()} must exceed bound_min {lo.tolist()} on every axis")
    return [np.linspace(lo[i], hi[i], resolution) for i in range(3)]


def _evaluate_grid(sdf_fn: SdfFn, axes: list[np.ndarray], chunk: int, device) -> np.ndarray:
    """(R, R, R) float32 SDF volume, volume[i, j, k] = sdf(x_i, y_j, z_k)."""
    R = len(axes[0])
    ax = [torch.as_tensor(a, dtype=torch.float32, device=device) for a in axes]
    yz = torch.stack(torch.meshgrid(ax[1], ax[2], indexing="ij"), dim=-1).reshape(-1, 2)
    out = np.empty((R, R * R), dtype=np.float32)
    # Points are built a few x-slabs at a time: a full (R^3, 3) array would
    # need 1.6 GB at R = 512.
    slabs = max(1, chunk // (R * R))
    with torch.no_grad():
        for i0 in range(0, R, slabs):
            xs = ax[0][i0 : i0 + slabs]
            pts = torch.cat([xs.repeat_interleave(R * R)[:, None], yz.repeat(len(xs), 1)], dim=-1)
            vals = [sdf_fn(pts[s : s + chunk]).reshape(-1).float().cpu() for s in range(0, len(pts), chunk)]
            out[i0 : i0 + len(xs)] = torch.cat(vals).numpy().reshape(len(xs), R * R)
    return out.reshape(R, R, R)


def _vertex_colors(color_fn: ColorFn, mesh: trimesh.Trimesh, chunk: int, device) -> np.ndarray:
    """(V, 3) uint8 colours of color_fn at the vertices with the mesh's vertex normals."""
    verts = torch.as_tensor(mesh.vertices, dtype=torch.float32, device=device)
    normals = torch.tensor(np.array(mesh.vertex_normals), dtype=torch.float32, device=device)
    parts = []
    with torch.no_grad():
        for s in range(0, len(verts), chunk):
            parts.append(color_fn(verts[s : s + chunk], normals[s : s + chunk]).float().cpu())
    rgb = torch.cat(parts).clamp(0, 1).numpy()
    return np.round(rgb * 255.0).astype(np.uint8)


def extract_mesh(
    sdf_fn: SdfFn,
    color_fn: ColorFn | None,
    bound_min,
    bound_max,
    resolution: int,
    chunk: int = 65536,
    device=None,
) -> trimesh.Trimesh:
    """Zero level set of `sdf_fn` inside the box [bound_min, bound_max].

    sdf_fn: (N, 3) float32 points -> (N,) SDF, positive outside the surface.
    color_fn: (N, 3) vertices and (N, 3) unit outward normals -> (N, 3) RGB in
        [0, 1], or None for no colours.
    bound_min, bound_max: (3,) box corners; resolution: samples per axis (the
        voxel size is extent / (resolution - 1)); chunk: points per call.
    Returns a mesh with world-coordinate vertices, outward-facing faces and
    uint8 vertex colours; an empty mesh when the SDF has no zero crossing.
    """
    axes = _grid_axes(bound_min, bound_max, resolution)
    volume = _evaluate_grid(sdf_fn, axes, chunk, device)
    finite = volume[np.isfinite(volume)]
    if finite.size == 0 or finite.min() >= 0 or finite.max() <= 0:
        return trimesh.Trimesh()
    # Non-finite samples (e.g. outside a network's domain) count as empty space.
    volume = np.nan_to_num(volume, nan=finite.max(), posinf=finite.max(), neginf=finite.min())
    spacing = tuple(float(a[1] - a[0]) for a in axes)
    # skimage's default winding ("descent") gives counter-clockwise faces seen
    # from the positive side, i.e. outward normals for an SDF positive outside.
    verts, faces, _, _ = marching_cubes(volume, level=0.0, spacing=spacing)
    verts = verts.astype(np.float64) + np.array([a[0] for a in axes])
    mesh = trimesh.Trimesh(vertices=verts, faces=faces, process=False)
    if color_fn is not None:
        mesh.visual.vertex_colors = _vertex_colors(color_fn, mesh, chunk, device)
    return mesh


def _in_frustum(verts: torch.Tensor, T_world_cam: torch.Tensor, intr: Intrinsics, near: float, far) -> torch.Tensor:
    """(V,) bool: vertices (V, 3) world inside the camera's image and depth range."""
    p_cam = transform_points(invert(T_world_cam), verts)
    uv, z = project(p_cam, intr)
    inside = (z >= near) & in_image(uv, intr)
    return inside if far is None else inside & (z <= far)


def cull_to_frustums(
    mesh: trimesh.Trimesh,
    poses,
    intr: Intrinsics,
    near: float = 0.05,
    far: float | None = None,
) -> trimesh.Trimesh:
    """Copy of `mesh` without the faces seen by no camera.

    poses: (N, 4, 4) T_world_cam (numpy or torch). A face is kept when at least
    one of its vertices is inside at least one frustum (z-depth in [near, far],
    projection inside the image); no occlusion test. Vertex colours are kept.
    """
    if len(mesh.faces) == 0:
        return mesh.copy()
    verts = torch.as_tensor(np.asarray(mesh.vertices), dtype=torch.float64)
    T = torch.as_tensor(np.asarray(poses), dtype=torch.float64).reshape(-1, 4, 4)
    seen = torch.zeros(len(verts), dtype=torch.bool)
    for T_world_cam in T:
        seen |= _in_frustum(verts, T_world_cam, intr, near, far)
    keep = seen.numpy()[np.asarray(mesh.faces)].any(axis=1)
    out = mesh.copy()
    out.update_faces(keep)
    out.remove_unreferenced_vertices()
    return out
