"""The Schur-complement bundle adjustment against scipy's least squares (the reference) on a
synthetic forward-driving window with known truth."""
import numpy as np
import pytest

from tests.nicer_stream.frontend.local_ba_reference import bundle_adjust
from nicer_stream.frontend.schur_ba import bundle_adjust_schur, huber_cost
from nicer_stream.geometry.se3 import so3_exp_np as so3_exp
from nicer_stream.types import Intrinsics

INTR = Intrinsics(228.5, 228.5, 159.5, 119.5, 320, 240)


def _pose(w, t):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = so3_exp(np.asarray(w, float)[None])[0], t
    return T


def _window(n_cams=10, n_pts=800, noise_px=0.1, outliers=10, seed=0):
    """Cameras driving along +z (1 m a frame, swaying), points 3-30 m beyond the last; observations with
    pixel noise and a few gross outliers. Returns (true poses, true points, cam, pt, uv)."""
    rng = np.random.default_rng(seed)
    poses = [_pose([0.0, 0.02 * np.sin(c), 0.0], [0.3 * np.sin(c / 2), 0.0, float(c)]) for c in range(n_cams)]
    X = np.stack([rng.uniform(-12, 12, n_pts), rng.uniform(-3, 3, n_pts), rng.uniform(3, 30, n_pts) + n_cams], 1)
    cam, pt, uv = [], [], []
    for c, T in enumerate(poses):
        Tcw = np.linalg.inv(T)
        p = X @ Tcw[:3, :3].T + Tcw[:3, 3]
        u = np.stack([INTR.fx * p[:, 0] / p[:, 2] + INTR.cx, INTR.fy * p[:, 1] / p[:, 2] + INTR.cy], 1)
        ok = (p[:, 2] > 0.5) & (u[:, 0] > 0) & (u[:, 0] < INTR.width) & (u[:, 1] > 0) & (u[:, 1] < INTR.height)
        cam += [c] * int(ok.sum())
        pt += np.flatnonzero(ok).tolist()
        uv.append(u[ok] + rng.normal(0, noise_px, (int(ok.sum()), 2)))
    cam, pt, uv = np.array(cam), np.array(pt), np.concatenate(uv)
    uv[rng.choice(len(uv), outliers, replace=False)] += 25.0
    return poses, X, cam, pt, uv


def _perturbed(poses, X, n_fixed, seed=1):
    rng = np.random.default_rng(seed)
    noisy = poses[:n_fixed] + [T @ _pose(rng.normal(0, 0.003, 3), rng.normal(0, 0.05, 3)) for T in poses[n_fixed:]]
    return noisy, X * (1 + rng.normal(0, 0.05, (len(X), 1)))  # 5% depth errors along the rays


def _cost(poses, X, cam, pt, uv):
    cw = np.stack([np.linalg.inv(T) for T in poses])
    p = np.einsum("mij,mj->mi", cw[cam, :3, :3], X[pt]) + cw[cam, :3, 3]
    r = np.stack([INTR.fx * p[:, 0] / p[:, 2] + INTR.cx, INTR.fy * p[:, 1] / p[:, 2] + INTR.cy], 1) - uv
    return huber_cost(r, 2.0)


def test_schur_reaches_the_reference_minimum_and_the_truth():
    poses, X, cam, pt, uv = _window()
    noisy, Xn = _perturbed(poses, X, 2)
    ref_p, ref_X, _ = bundle_adjust(noisy, 2, Xn, cam, pt, uv, INTR, 2.0, max_nfev=200)
    got_p, got_X, rms = bundle_adjust_schur(noisy, 2, Xn, cam, pt, uv, INTR, 2.0, max_iters=50)
    start, ref, got = _cost(noisy, Xn, cam, pt, uv), _cost(ref_p, ref_X, cam, pt, uv), _cost(got_p, got_X, cam, pt, uv)
    truth = _cost(poses, X, cam, pt, uv)
    assert got <= ref * 1.01 and got <= truth, (got, ref, truth, start)  # a minimum, as deep as scipy's
    for T_true, T_got in zip(poses, got_p):
        assert np.linalg.norm(T_got[:3, 3] - T_true[:3, 3]) < 0.05  # 0.5% of the 10 m window
    assert 0.08 < rms < 0.2  # 0.1 px per axis: ~0.14 px per observation


def test_fixed_poses_stay_and_outliers_do_not_pull():
    poses, X, cam, pt, uv = _window(outliers=200, seed=3)
    noisy, Xn = _perturbed(poses, X, 3, seed=4)
    got_p, _, _ = bundle_adjust_schur(noisy, 3, Xn, cam, pt, uv, INTR, 2.0)
    for k in range(3):
        np.testing.assert_array_equal(got_p[k], noisy[k])
    assert max(np.linalg.norm(a[:3, 3] - b[:3, 3]) for a, b in zip(got_p, poses)) < 0.05


@pytest.mark.parametrize("n_fixed", [8, 2])
def test_points_only_and_an_exact_start_stay_put(n_fixed):
    """All poses fixed: only the points move (back onto the truth); an exact start is a minimum."""
    poses, X, cam, pt, uv = _window(noise_px=0.0, outliers=0)
    got_p, got_X, rms = bundle_adjust_schur(poses, n_fixed, X * 1.02, cam, pt, uv, INTR, 2.0, max_iters=50)
    assert np.median(np.linalg.norm(got_X - X, axis=1)) < 1e-3
    assert rms < 1e-3
    _, same_X, _ = bundle_adjust_schur(poses, n_fixed, X, cam, pt, uv, INTR, 2.0)
    np.testing.assert_allclose(same_X, X, atol=1e-9)
