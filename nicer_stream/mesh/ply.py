"""Binary PLY writer for triangle meshes with per-vertex RGB colours.

Plain `x y z` float32 + `red green blue` uchar vertices and a
`vertex_indices` face list: readable by trimesh, Open3D and MeshLab.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh


def _vertex_rgb(mesh: trimesh.Trimesh) -> np.ndarray | None:
    """(V, 3) uint8 vertex colours, or None when the mesh has none."""
    if mesh.visual.kind != "vertex":
        return None
    return np.asarray(mesh.visual.vertex_colors)[:, :3].astype(np.uint8)


def write_ply(mesh: trimesh.Trimesh, path: str | Path) -> Path:
    """Write `mesh` as little-endian binary PLY to `path` (parents created). Returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    verts = np.asarray(mesh.vertices, dtype=np.float32).reshape(-1, 3)
    faces = np.asarray(mesh.faces, dtype=np.int32).reshape(-1, 3)
    rgb = _vertex_rgb(mesh) if len(verts) else None

    vdtype = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if rgb is not None:
        vdtype += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    vdata = np.empty(len(verts), dtype=vdtype)
    vdata["x"], vdata["y"], vdata["z"] = verts.T
    if rgb is not None:
        vdata["red"], vdata["green"], vdata["blue"] = rgb.T
    fdata = np.empty(len(faces), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    fdata["n"], fdata["i"] = 3, faces

    header = ["ply", "format binary_little_endian 1.0", "comment nicer-stream mesh", f"element vertex {len(verts)}"]
    header += [f"property float {a}" for a in "xyz"]
    if rgb is not None:
        header += [f"property uchar {c}" for c in ("red", "green", "blue")]
    header += [f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header"]
    with path.open("wb") as f:
        f.write(("\n".join(header) + "\n").encode("ascii"))
        f.write(vdata.tobytes())
        f.write(fdata.tobytes())
    return path
