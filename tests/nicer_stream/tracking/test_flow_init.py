"""Flow initialisation of tracking: PnP closed form and robustness, and on a fitted map."""
import numpy as np
import torch

from nicer_stream.geometry.se3 import se3_exp
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.priors.oracle import OracleFlow
from nicer_stream.geometry.pose_estimation import pnp_pose
from nicer_stream.tracking.flow_init import pose_from_flows
from nicer_stream.types import Intrinsics, Priors


def _scene(n=400, seed=0):
    rng = np.random.default_rng(seed)
    intr = Intrinsics(fx=200.0, fy=200.0, cx=160.0, cy=120.0, width=320, height=240)
    T = se3_exp(torch.tensor([0.1, -0.05, 0.2, 0.05, 0.1, -0.03], dtype=torch.float64)).numpy()
    p_cam = np.stack([rng.uniform(-1, 1, n), rng.uniform(-0.8, 0.8, n), rng.uniform(1.5, 4.0, n)], -1)
    X = p_cam @ T[:3, :3].T + T[:3, 3]
    uv = np.stack([intr.fx * p_cam[:, 0] / p_cam[:, 2] + intr.cx, intr.fy * p_cam[:, 1] / p_cam[:, 2] + intr.cy], -1)
    return X, uv, intr, T


def test_pnp_recovers_exact_pose_with_outliers():
    X, uv, intr, T = _scene()
    uv[:80] += np.random.default_rng(1).uniform(-40, 40, (80, 2))  # 20% gross outliers
    T_est, inliers = pnp_pose(X, uv, intr, np.eye(4))
    assert np.abs(T_est - T).max() < 1e-6
    assert 315 <= inliers <= 330


def test_pnp_refuses_too_few_points():
    X, uv, intr, _ = _scene(n=10)
    assert pnp_pose(X, uv, intr, np.eye(4)) is None


def test_flow_init_recovers_perturbed_pose(fitted, pose_error):
    """PnP on the (oracle) flow from the previous frame, lifted with the map's rendered
    depth, lands far closer to the true pose than the perturbed guess it starts from."""
    cfg, frames, mfs, poses, model, beta = fitted
    src, dst = frames[3], frames[4]
    flow = OracleFlow().flow(src, dst)
    src_mf = MapFrame.from_frame(src.without_ground_truth(), Priors(src.index, "oracle", flows=[flow]), torch.device("cpu"))
    T_gt = poses[dst.index]
    T_guess = poses[src.index]
    T = pose_from_flows([(src_mf, poses[src.index])], mfs[4], T_guess, model, beta, cfg.render, 500,
                        torch.Generator().manual_seed(0))
    assert T is not None
    t0, r0 = pose_error(T_gt, T_guess)
    t1, r1 = pose_error(T_gt, T)
    assert t1 < 0.3 * t0 and r1 < 0.3 * r0 + 1e-3, (t0, t1, r0, r1)
    # No flow to the new frame: no solution (the caller keeps its fallback).
    assert pose_from_flows([(mfs[3], poses[src.index])], mfs[4], T_guess, model, beta, cfg.render, 500,
                           torch.Generator().manual_seed(0)) is None
