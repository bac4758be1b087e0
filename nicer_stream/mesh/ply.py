"""The mesh file: binary little-endian PLY with float32 vertices and, where the mesh has them,
per-vertex RGBA colours (trimesh's exporter: readable by trimesh, Open3D and MeshLab)."""
from __future__ import annotations

from pathlib import Path

import trimesh


def write_ply(mesh: trimesh.Trimesh, path: str | Path) -> Path:
    """Write `mesh` as binary PLY to `path` (parents created), without normals. Returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(trimesh.exchange.ply.export_ply(mesh, encoding="binary", vertex_normal=False))
    return path
