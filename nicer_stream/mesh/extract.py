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
from nicer_stream.mesh.sparse_grid import JumpFn, SdfFn, evaluate_grid_sparse
from nicer_stream.types import Intrinsics

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


def _vertex_colors(color_fn: ColorFn, mesh: trimesh.Trimesh, chunk: int) -> np.ndarray:
    """(V, 3) uint8 colours of color_fn at the vertices with the mesh's vertex normals."""
    verts = torch.as_tensor(mesh.vertices, dtype=torch.float32)
    normals = torch.tensor(np.array(mesh.vertex_normals), dtype=torch.float32)
    with torch.no_grad():
        parts = [color_fn(verts[s : s + chunk], normals[s : s + chunk]).float().cpu()
                 for s in range(0, len(verts), chunk)]
    rgb = torch.cat(parts).clamp(0, 1).numpy()
    return np.round(rgb * 255.0).astype(np.uint8)


def extract_mesh(
    sdf_fn: SdfFn,
    color_fn: ColorFn | None,
    bound_min,
    bound_max,
    resolution: int,
    chunk: int = 65536,
    jump_fn: JumpFn | None = None,
) -> trimesh.Trimesh:
    """Zero level set of `sdf_fn` inside the box [bound_min, bound_max].

    sdf_fn: (N, 3) float32 points -> (N,) SDF, positive outside the surface.
    color_fn: (N, 3) vertices and (N, 3) unit outward normals -> (N, 3) RGB in
        [0, 1], or None for no colours.
    bound_min, bound_max: (3,) box corners; resolution: samples per axis (the
        voxel size is extent / (resolution - 1)); chunk: points per call.
    sdf_fn is evaluated coarse to fine, densely only near its zero crossings
        (`sparse_grid.evaluate_grid_sparse`: a fraction of the resolution^3
        calls), assuming it is L-Lipschitz with L < 4 (a learnt SDF is about 1)
        inside every box jump_fn clears.
    jump_fn: boxes lo (B, 3), hi (B, 3) -> (B,) bool, True where sdf_fn may
        be discontinuous inside [lo, hi] (e.g. a constant outside observed
        voxels: boxes holding observed and unobserved ones), which the sparse
        grid then evaluates densely; None: sdf_fn is continuous.
    Returns a mesh with world-coordinate vertices, outward-facing faces and
    uint8 vertex colours; an empty mesh when the SDF has no zero crossing.
    Both paths give the same mesh under that assumption, except next to
    non-finite samples: those take the volume's largest (for -inf smallest)
    finite value, which the sparse volume may not hold, so vertices on their
    edges can sit elsewhere along the edge.
    """
    axes = _grid_axes(bound_min, bound_max, resolution)
    volume = evaluate_grid_sparse(sdf_fn, axes, chunk, None, jump_fn=jump_fn)
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
        mesh.visual.vertex_colors = _vertex_colors(color_fn, mesh, chunk)
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
