"""Ground-truth meshes of synthetic scenes (trimesh, world frame, metres).

Each object is a closed, watertight, outward-oriented mesh; the room is a closed
box whose faces point inwards (what a camera inside sees). Vertex colours use
the renderer's shading, so the mesh looks like the images (up to tessellation).
Curved surfaces are tessellated finely enough that the mesh is within ~0.1 mm of
the analytic surface for the object sizes used here (measured: < 0.05 mm).
"""
from __future__ import annotations

import numpy as np
import trimesh

from sources.synthetic.primitives import Box, Cylinder, Sphere
from sources.synthetic.render import Surface, shade


def _box_mesh(half: np.ndarray, max_edge: float) -> trimesh.Trimesh:
    """Axis-aligned box centred at the origin, each face a regular grid (edges <= max_edge-ish)."""
    n = np.maximum(1, np.ceil(2 * half / max_edge).astype(int))
    verts, faces = [], []
    for k in range(3):
        i, j = [a for a in range(3) if a != k]
        gi = np.linspace(-half[i], half[i], n[i] + 1)
        gj = np.linspace(-half[j], half[j], n[j] + 1)
        A, B = np.meshgrid(gi, gj, indexing="ij")
        ids = np.arange(A.size).reshape(A.shape)
        a, b, c, d = ids[:-1, :-1], ids[1:, :-1], ids[1:, 1:], ids[:-1, 1:]
        quads = np.stack([a, b, c, d], -1).reshape(-1, 4)
        for sign in (-1.0, 1.0):
            v = np.zeros((A.size, 3))
            v[:, i], v[:, j], v[:, k] = A.ravel(), B.ravel(), sign * half[k]
            tri = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
            # Orient each face outwards: e_i x e_j = +-e_k decides the winding.
            if sign * np.cross(np.eye(3)[i], np.eye(3)[j])[k] < 0:
                tri = tri[:, ::-1]
            faces.append(tri + sum(len(x) for x in verts))
            verts.append(v)
    mesh = trimesh.Trimesh(np.concatenate(verts), np.concatenate(faces), process=False)
    mesh.merge_vertices()
    return mesh


def _cylinder_mesh(radius: float, half_height: float, max_edge: float) -> trimesh.Trimesh:
    """Capped cylinder along z, centred at the origin, as a surface of revolution."""
    nr = max(2, int(np.ceil(radius / max_edge)))
    nz = max(2, int(np.ceil(2 * half_height / max_edge)))
    r = np.linspace(0.0, radius, nr + 1)
    z = np.linspace(-half_height, half_height, nz + 1)
    profile = np.concatenate(
        [
            np.stack([r, np.full_like(r, -half_height)], -1),
            np.stack([np.full(nz - 1, radius), z[1:-1]], -1),
            np.stack([r[::-1], np.full_like(r, half_height)], -1),
        ]
    )
    # ~0.1 mm sagitta at r = 0.3 m: r * (1 - cos(pi / sections)).
    return trimesh.creation.revolve(profile, sections=192)


def primitive_mesh(shape, max_edge: float = 0.05) -> trimesh.Trimesh:
    """Watertight trimesh of one primitive in world coordinates (inside-out for a room box)."""
    if isinstance(shape, Sphere):
        mesh = trimesh.creation.icosphere(subdivisions=5, radius=shape.radius)
        mesh.apply_translation(shape.centre)
        return mesh
    if isinstance(shape, Box):
        mesh = _box_mesh(np.asarray(shape.half, dtype=float), max_edge)
    elif isinstance(shape, Cylinder):
        mesh = _cylinder_mesh(shape.radius, shape.half_height, max_edge)
    else:
        raise TypeError(f"no mesh for {type(shape).__name__}")
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = shape.R, shape.centre
    mesh.apply_transform(T)
    if isinstance(shape, Box) and shape.inside:
        mesh.invert()
    return mesh


def surface_meshes(surfaces: list[Surface], light: np.ndarray, max_edge: float = 0.05) -> list[trimesh.Trimesh]:
    """One coloured mesh per surface, vertex colours = rendered shading at each vertex."""
    out = []
    for s in surfaces:
        mesh = primitive_mesh(s.shape, max_edge)
        idx = np.zeros(len(mesh.vertices), dtype=int)
        rgb = shade([s], idx, np.asarray(mesh.vertices).T, np.asarray(mesh.vertex_normals).T, light).T
        rgba = np.concatenate([np.round(rgb * 255), np.full((len(rgb), 1), 255)], -1).astype(np.uint8)
        mesh.visual = trimesh.visual.ColorVisuals(mesh, vertex_colors=rgba)
        out.append(mesh)
    return out


def scene_mesh(surfaces: list[Surface], light: np.ndarray, max_edge: float = 0.05) -> trimesh.Trimesh:
    """All surfaces as one trimesh with vertex colours (uint8 RGBA)."""
    return trimesh.util.concatenate(surface_meshes(surfaces, light, max_edge))
