"""Mesh metrics, GT culling and the GT-depth reference cloud."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from nicer_stream.eval.mesh import CullCamera, SurfaceSamples, cull_observed, mesh_metrics, sample_mesh
from nicer_stream.eval.reference import ReferenceBuilder, normals_from_points
from nicer_stream.geometry.depth_normals import unproject_depth
from nicer_stream.types import Intrinsics

N = 20_000


def plane(z: float = 0.0, size: float = 1.0) -> trimesh.Trimesh:
    """A size x size square in the plane z = const (two triangles), normal +z."""
    h = size / 2
    v = np.array([[-h, -h, z], [h, -h, z], [h, h, z], [-h, h, z]])
    return trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], process=False)


def test_identical_samples_give_zero():
    s = sample_mesh(trimesh.creation.icosphere(subdivisions=2), N, seed=0)
    m = mesh_metrics(s, s)
    assert m.acc_m == 0 and m.comp_m == 0 and m.comp_ratio == 1.0
    assert m.normal_consistency == pytest.approx(1.0)


def test_same_mesh_different_samples_is_near_zero():
    sphere = trimesh.creation.icosphere(subdivisions=3)
    m = mesh_metrics(sample_mesh(sphere, N, seed=0), sample_mesh(sphere, N, seed=1))
    assert m.acc_m < 0.02 and m.comp_m < 0.02 and m.comp_ratio == 1.0
    assert m.normal_consistency > 0.99


@pytest.mark.parametrize("d", [0.03, 0.07])
def test_plane_shifted_along_normal(d):
    est, gt = sample_mesh(plane(d), N, seed=0), sample_mesh(plane(0.0), N, seed=0)
    m = mesh_metrics(est, gt)
    assert m.acc_m == pytest.approx(d, abs=1e-9)
    assert m.comp_m == pytest.approx(d, abs=1e-9)
    assert m.comp_ratio == (1.0 if d < 0.05 else 0.0)
    # Independent samples: nearest neighbours are off to the side too, but only slightly.
    m2 = mesh_metrics(sample_mesh(plane(d), N, seed=3), gt)
    assert d <= m2.acc_m < d + 0.005 and d <= m2.comp_m < d + 0.005


def test_normal_consistency_is_mean_abs_cosine():
    pts = sample_mesh(plane(), 2000, seed=0).points
    up = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    a = np.radians(60)
    tilted = np.tile([np.sin(a), 0.0, np.cos(a)], (len(pts), 1))
    assert mesh_metrics(SurfaceSamples(pts, tilted), SurfaceSamples(pts, up)).normal_consistency == pytest.approx(0.5)
    assert mesh_metrics(SurfaceSamples(pts, -up), SurfaceSamples(pts, up)).normal_consistency == pytest.approx(1.0)
    assert mesh_metrics(SurfaceSamples(pts), SurfaceSamples(pts, up)).normal_consistency is None


INTR = Intrinsics(50.0, 50.0, 49.5, 39.5, 100, 80)


def test_cull_removes_points_behind_outside_and_occluded():
    pts = np.array([
        [0.0, 0.0, 1.5],   # 0 on the observed surface: kept
        [0.0, 0.0, -1.5],  # 1 behind the camera
        [10.0, 0.0, 1.5],  # 2 outside the image
        [0.0, 0.0, 3.0],   # 3 occluded by the surface at 1.5 m
        [0.1, 0.1, 1.53],  # 4 within the depth tolerance: kept
        [-0.9, 0.0, 1.5],  # 5 where GT depth is invalid (0)
    ])
    depth = np.full((80, 100), 1.5, np.float32)
    depth[:, :30] = 0.0
    cam = CullCamera(np.eye(4), INTR, depth)
    assert cull_observed(pts, [cam], depth_tol=0.05).tolist() == [True, False, False, False, True, False]
    # Without depth only the frustum test applies.
    assert cull_observed(pts, [CullCamera(np.eye(4), INTR)]).tolist() == [True, False, False, True, True, True]


def test_cull_union_over_cameras_uses_pose():
    # A second camera at z = 5 looking back along -z (rotation pi about y) sees the far side.
    T = np.eye(4)
    T[:3, :3] = np.diag([-1.0, 1.0, -1.0])
    T[2, 3] = 5.0
    pts = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 6.0]])
    assert cull_observed(pts, [CullCamera(np.eye(4), INTR)]).tolist() == [False, True]
    assert cull_observed(pts, [CullCamera(T, INTR)]).tolist() == [True, False]
    both = cull_observed(pts, [CullCamera(np.eye(4), INTR), CullCamera(T, INTR)])
    assert both.tolist() == [True, True]


def tilted_plane_depth(intr: Intrinsics, n: np.ndarray, offset: float) -> np.ndarray:
    """z-depth of the plane {p : n . p = offset} seen by a camera at the origin."""
    v, u = np.mgrid[0 : intr.height, 0 : intr.width]
    dirs = np.stack([(u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy, np.ones(u.shape)], -1)
    return (offset / (dirs @ n)).astype(np.float32)


def test_reference_from_plane_depth():
    n = np.array([0.3, -0.2, -1.0])
    n /= np.linalg.norm(n)  # faces the camera (n . z < 0)
    depth = tilted_plane_depth(INTR, n, -2.0)
    P = unproject_depth(depth, INTR)
    normals, valid = normals_from_points(P, depth.astype(np.float64))
    assert valid[1:-1, 1:-1].all() and not valid[0].any()
    np.testing.assert_allclose(normals[valid], np.broadcast_to(n, normals[valid].shape), atol=1e-4)
    # World points through a non-identity GT pose stay on the transformed plane.
    T = np.eye(4)
    T[:3, 3] = [1.0, 2.0, 3.0]
    b = ReferenceBuilder(voxel=0.05)
    b.add(depth, INTR, T)
    ref = b.build()
    assert 100 < len(ref.points) < valid.sum()
    np.testing.assert_allclose((ref.points - T[:3, 3]) @ n, -2.0, atol=1e-3)
    np.testing.assert_allclose(np.abs(ref.normals @ n), 1.0, atol=1e-4)


def test_reference_drops_depth_edges_and_empty():
    depth = np.full((80, 100), 2.0, np.float32)
    depth[:, 50:] = 4.0  # a step edge: normals there would be bogus
    _, valid = normals_from_points(unproject_depth(depth, INTR), depth.astype(np.float64))
    assert not valid[:, 49:51].any() and valid[5:-5, 5:45].all()
    assert ReferenceBuilder().build() is None


def test_voxel_downsample_averages_per_voxel():
    from nicer_stream.eval.reference import voxel_downsample

    pts = np.array([[0.01, 0.01, 0.01], [0.03, 0.01, 0.01], [0.51, 0.0, 0.0], [-0.01, 0.0, 0.0]])
    nrm = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    out = voxel_downsample(SurfaceSamples(pts, nrm), voxel=0.1)
    order = np.argsort(out.points[:, 0])
    np.testing.assert_allclose(out.points[order], [[-0.01, 0, 0], [0.02, 0.01, 0.01], [0.51, 0, 0]])
    np.testing.assert_allclose(out.normals[order][1], [np.sqrt(0.5), np.sqrt(0.5), 0.0])
