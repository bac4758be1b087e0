"""ATE / RPE / Umeyama: invariances, closed forms, recovery of known transforms."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from nicer_stream.eval.trajectory import Sim3, ate, pose_sim3, relative_errors, rpe, umeyama
from nicer_stream.geometry.se3 import se3_exp
from tests.nicer_stream.geometry.rotations import so3_exp
from tests.nicer_stream.eval.sim3_poses import apply_poses


def random_rotation(rng) -> np.ndarray:
    return so3_exp(torch.from_numpy(rng.normal(size=3) * 1.5)).numpy()


def random_path(rng, n: int = 30) -> np.ndarray:
    """(n, 4, 4) a wiggly non-planar camera path with varying orientation."""
    xi = np.concatenate([np.cumsum(rng.normal(size=(n, 3)) * 0.1, 0), rng.normal(size=(n, 3)) * 0.5], 1)
    return se3_exp(torch.from_numpy(xi)).numpy()


def sim3_of(rng, with_scale: bool) -> Sim3:
    return Sim3(random_rotation(rng), rng.normal(size=3) * 3, float(rng.uniform(0.2, 5)) if with_scale else 1.0)


def test_umeyama_recovers_known_sim3():
    rng = np.random.default_rng(0)
    src = rng.normal(size=(50, 3))
    true = sim3_of(rng, with_scale=True)
    got = umeyama(src, true.apply_points(src), with_scale=True)
    np.testing.assert_allclose(got.R, true.R, atol=1e-10)
    np.testing.assert_allclose(got.t, true.t, atol=1e-10)
    assert got.scale == pytest.approx(true.scale, rel=1e-10)
    assert np.linalg.det(got.R) == pytest.approx(1.0)


def test_umeyama_returns_rotation_not_reflection():
    rng = np.random.default_rng(1)
    src = rng.normal(size=(40, 3))
    dst = src * np.array([1.0, 1.0, -1.0])  # a mirror image: best proper rotation must still have det +1
    assert np.linalg.det(umeyama(src, dst).R) == pytest.approx(1.0)


@pytest.mark.parametrize("seed", [2, 3, 4])
def test_ate_invariant_to_sim3_of_estimate(seed):
    rng = np.random.default_rng(seed)
    gt = random_path(rng)
    est = gt.copy()
    est[:, :3, 3] += rng.normal(size=(len(gt), 3)) * 0.05
    base = ate(est, gt, with_scale=True).rmse_m
    assert base > 1e-3
    moved = apply_poses(sim3_of(rng, with_scale=True), est)
    assert ate(moved, gt, with_scale=True).rmse_m == pytest.approx(base, rel=1e-9)
    base_se3 = ate(est, gt, with_scale=False).rmse_m
    moved_se3 = apply_poses(sim3_of(rng, with_scale=False), est)
    assert ate(moved_se3, gt, with_scale=False).rmse_m == pytest.approx(base_se3, rel=1e-9)
    # A scale change is not absorbed by SE(3) alignment.
    assert ate(apply_poses(Sim3(np.eye(3), np.zeros(3), 2.0), est), gt, with_scale=False).rmse_m > 2 * base_se3


def test_constant_offset_gives_zero_ate():
    rng = np.random.default_rng(5)
    gt = random_path(rng)
    est = gt.copy()
    est[:, :3, 3] += np.array([0.3, -1.0, 2.0])
    assert ate(est, gt, with_scale=False).rmse_m < 1e-12
    assert ate(est, gt, with_scale=True).rmse_m < 1e-12


def test_one_displaced_point_closed_form():
    # Cube corners (centred, isotropic): displacing one of n points by d along a
    # direction e gives optimal SE(3) alignment = translation by d e / n, rotation I
    # (the cross-covariance stays symmetric PD), so RMSE = d sqrt((n - 1)) / n.
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    n, d = len(corners), 0.1
    gt = np.tile(np.eye(4), (n, 1, 1))
    gt[:, :3, 3] = corners
    est = gt.copy()
    est[0, :3, 3] += d * np.array([1.0, 1.0, 1.0]) / np.sqrt(3)  # along corner 0's own (radial) line
    res = ate(est, gt, with_scale=False)
    assert res.rmse_m == pytest.approx(d * np.sqrt(n - 1) / n, rel=1e-9)
    assert res.errors_m[0] == pytest.approx(d * (n - 1) / n, rel=1e-9)


def test_rpe_zero_for_aligned_and_scaled_copies():
    rng = np.random.default_rng(6)
    gt = random_path(rng)
    est = apply_poses(Sim3(random_rotation(rng), rng.normal(size=3), 1.0), gt)
    r = rpe(est, gt)
    assert r.trans_rmse_m < 1e-9 and r.rot_rmse_deg < 1e-6
    scaled = apply_poses(Sim3(np.eye(3), np.zeros(3), 0.5), gt)
    assert rpe(scaled, gt, scale=2.0).trans_rmse_m < 1e-9
    assert rpe(scaled, gt, scale=1.0).trans_rmse_m > 1e-3


def test_rpe_known_perturbation():
    # Perturb frame k by a right-multiplied delta: pairs (k-1, k) and (k, k+1) see it.
    rng = np.random.default_rng(7)
    gt = random_path(rng, 10)
    k, angle, shift = 4, np.radians(2.0), 0.03
    delta = se3_exp(torch.tensor([shift, 0.0, 0.0, 0.0, 0.0, angle], dtype=torch.float64)).numpy()
    est = gt.copy()
    est[k] = gt[k] @ delta
    trans, rot = relative_errors(est, gt)
    # Pair (k-1, k): E = delta exactly. Pair (k, k+1): E = inv(rel_g) inv(delta) rel_g, same angle.
    assert rot[k - 1] == pytest.approx(angle, rel=1e-9) and rot[k] == pytest.approx(angle, rel=1e-9)
    assert trans[k - 1] == pytest.approx(np.linalg.norm(delta[:3, 3]), rel=1e-9)
    assert np.all(rot[[i for i in range(len(rot)) if i not in (k - 1, k)]] < 1e-7)
    r = rpe(est, gt)
    assert r.rot_rmse_deg == pytest.approx(2.0 * np.sqrt(2 / 9), rel=1e-6)


def test_pose_sim3_recovers_known_sim3():
    rng = np.random.default_rng(7)
    est = random_path(rng)
    true = sim3_of(rng, with_scale=True)
    got = pose_sim3(est, apply_poses(true, est))
    np.testing.assert_allclose(got.R, true.R, atol=1e-9)
    np.testing.assert_allclose(got.t, true.t, atol=1e-9)
    assert got.scale == pytest.approx(true.scale, rel=1e-9)


def test_pose_sim3_fixes_the_rotation_that_a_straight_path_leaves_free():
    """Camera centres on a line with 2 mm of noise: Umeyama's rotation about the line is
    arbitrary, the orientations pin it down."""
    rng = np.random.default_rng(8)
    n = 20
    gt = np.tile(np.eye(4), (n, 1, 1))
    gt[:, :3, :3] = random_rotation(rng)
    gt[:, :3, 3] = np.linspace(0, 0.2, n)[:, None] * np.array([1.0, 0.0, 0.0])
    true = sim3_of(rng, with_scale=True)
    est = apply_poses(Sim3(true.R.T, -true.R.T @ true.t / true.scale, 1 / true.scale), gt)  # inverse map
    est[:, :3, 3] += rng.normal(size=(n, 3)) * 0.002 / true.scale
    angle = lambda R: np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))
    assert angle(pose_sim3(est, gt).R @ true.R.T) < 0.5
    assert angle(umeyama(est[:, :3, 3], gt[:, :3, 3]).R @ true.R.T) > 5.0


def test_pose_sim3_static_camera_keeps_unit_scale():
    T = np.tile(np.eye(4), (5, 1, 1))
    assert pose_sim3(T, T).scale == 1.0
