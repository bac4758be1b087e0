"""Mesh extraction (marching cubes on the SDF), frustum culling and PLY output."""
from nicer_stream.mesh.extract import cull_to_frustums, extract_mesh
from nicer_stream.mesh.ply import write_ply

__all__ = ["cull_to_frustums", "extract_mesh", "write_ply"]
