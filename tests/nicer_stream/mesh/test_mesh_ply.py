import numpy as np
import trimesh

from nicer_stream.mesh.ply import write_ply


def _coloured_box():
    mesh = trimesh.creation.box(extents=(1.0, 2.0, 0.5))
    rgb = np.random.default_rng(7).integers(0, 256, (len(mesh.vertices), 3), dtype=np.uint8)
    mesh.visual.vertex_colors = rgb
    return mesh, rgb


def test_round_trip_keeps_vertices_faces_and_colours(tmp_path):
    mesh, rgb = _coloured_box()
    path = write_ply(mesh, tmp_path / "sub" / "mesh.ply")
    assert path.read_bytes().startswith(b"ply\nformat binary_little_endian 1.0\n")
    back = trimesh.load(path, process=False)
    assert len(back.vertices) == len(mesh.vertices)
    assert np.allclose(back.vertices, mesh.vertices, atol=1e-6)
    assert np.array_equal(back.faces, mesh.faces)
    assert np.array_equal(np.asarray(back.visual.vertex_colors)[:, :3], rgb)


def test_mesh_without_colours(tmp_path):
    mesh = trimesh.creation.icosphere(subdivisions=1)
    path = write_ply(mesh, tmp_path / "plain.ply")
    assert b"red" not in path.read_bytes().split(b"end_header")[0]
    back = trimesh.load(path, process=False)
    assert np.array_equal(back.faces, mesh.faces) and len(back.vertices) == len(mesh.vertices)
