"""Trimmed Sim(3) ICP of a surface onto a reference surface."""
from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh

from nicer_stream.eval.registration import compose, icp_sim3, pins_similarity, scale_change_trusted
from nicer_stream.eval.trajectory import Sim3
from tests.nicer_stream.geometry.rotations import so3_exp

IDENTITY = Sim3(np.eye(3), np.zeros(3), 1.0)


def room_points(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) samples and normals of a 4 x 3 x 2.5 m box with a table-sized box inside (not symmetric)."""
    room = trimesh.creation.box([4.0, 3.0, 2.5])
    table = trimesh.creation.box([1.0, 0.6, 0.8], trimesh.transformations.translation_matrix([0.8, -0.5, -0.85]))
    mesh = trimesh.util.concatenate([room, table])
    p, face = trimesh.sample.sample_surface(mesh, n, seed=seed)
    return np.asarray(p, np.float64), np.asarray(mesh.face_normals[face], np.float64)


def sim3(rotvec, t, s) -> Sim3:
    return Sim3(so3_exp(torch.tensor(rotvec, dtype=torch.float64)).numpy(), np.asarray(t, np.float64), s)


def angle_deg(R: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))))


def test_compose_applies_right_then_left():
    a, b = sim3([0.1, -0.2, 0.3], [1.0, 2.0, -1.0], 1.5), sim3([-0.3, 0.0, 0.2], [0.5, 0.0, 0.1], 0.8)
    x = np.random.default_rng(0).normal(size=(10, 3))
    np.testing.assert_allclose(compose(a, b).apply_points(x), a.apply_points(b.apply_points(x)), atol=1e-12)


def test_icp_recovers_a_similarity_from_a_perturbed_start_with_partial_overlap():
    truth = sim3([0.02, -0.03, 0.01], [0.05, -0.04, 0.03], 1.03)  # estimate -> reference
    dst, normals = room_points(60_000, seed=1)
    src = (room_points(60_000, seed=2)[0] - truth.t) @ truth.R / truth.scale  # same surface, estimate world
    src = src[src[:, 0] < 1.5]  # the estimate lacks one wall: those samples have no partner
    src = src + np.random.default_rng(3).normal(scale=0.003, size=src.shape)  # 3 mm surface noise
    start = sim3([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 1.0)  # ~2 deg, 7 cm and 3% from the truth
    got = icp_sim3(src, dst, start)
    assert got.scale == pytest.approx(truth.scale, rel=2e-3)
    assert angle_deg(got.R @ truth.R.T) < 0.1
    probe = src[:1000]
    assert np.abs(got.apply_points(probe) - truth.apply_points(probe)).max() < 0.01


def test_icp_keeps_the_start_without_overlap():
    dst, normals = room_points(5_000, seed=1)
    start = sim3([0.0, 0.0, 0.0], [100.0, 0.0, 0.0], 1.0)  # 100 m away: no pair within any radius
    assert icp_sim3(dst, dst, start) is start


def test_a_room_pins_a_similarity_and_a_plane_or_a_sphere_does_not():
    assert pins_similarity(*room_points(20_000, seed=0))
    rng = np.random.default_rng(0)
    plane = np.concatenate([rng.uniform(-2, 2, (5_000, 2)), np.full((5_000, 1), 2.0)], 1)
    assert not pins_similarity(plane, np.tile([0.0, 0.0, 1.0], (5_000, 1)))  # slides along itself
    ball = rng.normal(size=(5_000, 3))
    ball /= np.linalg.norm(ball, axis=1, keepdims=True)
    assert not pins_similarity(2.0 * ball, ball)  # spins about its centre


def test_scale_changes_beyond_the_limit_are_not_trusted():
    start = sim3([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 1.3)
    assert scale_change_trusted(start, sim3([0.1, 0.0, 0.0], [1.0, 0.0, 0.0], 1.3 * 1.05))
    assert scale_change_trusted(start, sim3([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 1.3 / 1.05))
    assert not scale_change_trusted(start, sim3([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 1.3 * 1.2))
    assert not scale_change_trusted(start, sim3([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 1.3 * 0.55))
