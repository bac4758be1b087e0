import numpy as np
import pytest
import torch

from nicer_stream.errors import UserError
from nicer_stream.mesh.extract import cull_to_frustums, extract_mesh
from nicer_stream.types import Intrinsics

R, RES = 0.5, 64
CENTRE = torch.tensor([0.1, -0.2, 0.05])


def _sphere_sdf(p):
    return (p - CENTRE.to(p)).norm(dim=-1) - R


def _normal_colour(p, n):
    return (n + 1) / 2


@pytest.fixture(scope="module")
def sphere():
    return extract_mesh(_sphere_sdf, _normal_colour, [-0.6, -0.8, -0.6], [0.8, 0.5, 0.7], RES, chunk=10000)


def test_sphere_is_watertight_at_the_right_radius_and_area(sphere):
    voxel = 1.4 / (RES - 1)
    r = np.linalg.norm(sphere.vertices - CENTRE.numpy(), axis=1)
    assert sphere.is_watertight
    assert np.abs(r - R).max() < voxel
    assert abs(sphere.area / (4 * np.pi * R**2) - 1) < 0.03
    assert abs(sphere.volume / (4 / 3 * np.pi * R**3) - 1) < 0.03  # > 0: faces wound outwards


def test_colours_come_from_color_fn_with_outward_normals(sphere):
    rgb = np.asarray(sphere.visual.vertex_colors)[:, :3]
    assert rgb.dtype == np.uint8 and len(rgb) == len(sphere.vertices)
    radial = sphere.vertices - CENTRE.numpy()
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    assert np.abs(rgb / 255 * 2 - 1 - radial).max() < 0.06


def test_no_zero_crossing_gives_empty_mesh():
    for offset in (2.0, -2.0):
        mesh = extract_mesh(lambda p: p.norm(dim=-1) - 10 + offset * 10, None, [-1] * 3, [1] * 3, 8)
        assert len(mesh.vertices) == 0 and len(mesh.faces) == 0


def test_bad_grid_is_a_one_line_user_error():
    with pytest.raises(UserError, match="resolution") as e:
        extract_mesh(_sphere_sdf, None, [-1] * 3, [1] * 3, 1)
    assert "\n" not in str(e.value)
    with pytest.raises(UserError, match="bound"):
        extract_mesh(_sphere_sdf, None, [-1] * 3, [1, -1, 1], 8)


def test_cull_removes_faces_behind_a_camera(sphere):
    intr = Intrinsics(fx=50.0, fy=50.0, cx=49.5, cy=49.5, width=100, height=100)
    T = np.eye(4)
    T[:3, 3] = CENTRE.numpy()  # camera at the centre looking along +z
    culled = cull_to_frustums(sphere, T[None], intr)
    z = culled.vertices[:, 2] - CENTRE.numpy()[2]
    # Every kept face has a vertex in front; faces behind (z < 0) are gone.
    assert 0 < len(culled.faces) < len(sphere.faces)
    assert (z[culled.faces].max(axis=1) > 0).all()
    assert np.asarray(culled.visual.vertex_colors).shape == (len(culled.vertices), 4)
    # A 90x90 degree square frustum spans 4 asin(sin^2 45 deg) = 2 pi / 3 sr,
    # 1/6 of the sphere; faces straddling its edges add a little.
    assert abs(culled.area / sphere.area - 1 / 6) < 0.02
    # A second camera looking the other way keeps the opposite sixth too.
    T2 = T.copy()
    T2[:3, :3] = np.diag([1.0, -1.0, -1.0])
    both = cull_to_frustums(sphere, np.stack([T, T2]), intr)
    assert abs(both.area / sphere.area - 1 / 3) < 0.04
    # In-frustum vertices have z >= R / sqrt(3) = 0.29: far = 0.25 clips them all.
    assert len(cull_to_frustums(sphere, T[None], intr, far=0.25).faces) == 0
    assert len(cull_to_frustums(sphere, T[None], intr, far=0.35).faces) > 0


def test_cull_keeps_everything_seen_and_accepts_torch_poses(sphere):
    intr = Intrinsics(fx=50.0, fy=50.0, cx=49.5, cy=49.5, width=100, height=100)
    T = torch.eye(4, dtype=torch.float64)
    T[:3, 3] = CENTRE.double() + torch.tensor([0.0, 0.0, -3.0])  # 3 m back, whole sphere in view
    kept = cull_to_frustums(sphere, T[None], intr)
    assert len(kept.faces) == len(sphere.faces) and len(kept.vertices) == len(sphere.vertices)


def test_plane_is_exact_and_chunking_does_not_change_the_grid():
    # Marching cubes interpolates linearly: a tilted plane is recovered exactly.
    n = torch.tensor([0.2, -0.5, 0.8])

    def sdf(p):
        return p @ n.to(p) - 0.1

    meshes = [extract_mesh(sdf, None, [-1, -0.5, -0.7], [0.9, 1, 0.6], 9, chunk=c) for c in (7, 81, 10**6)]
    assert len(meshes[0].faces) > 0
    assert np.abs(meshes[0].vertices @ n.numpy().astype(np.float64) - 0.1).max() < 1e-5
    for m in meshes[1:]:
        assert np.allclose(m.vertices, meshes[0].vertices, atol=1e-6) and np.array_equal(m.faces, meshes[0].faces)
