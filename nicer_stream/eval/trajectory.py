"""Trajectory metrics: Umeyama Sim(3)/SE(3) alignment, ATE RMSE, RPE.

Poses are (N, 4, 4) float64 `T_world_cam` (camera-to-world, metres); the
estimate lives in the SLAM world (first camera), the ground truth in the
dataset world. Alignment maps estimate positions onto GT positions.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from nicer_stream.geometry.se3 import rotation_angle


@dataclass(frozen=True)
class Sim3:
    """x_gt = scale * R @ x_est + t. R: (3, 3) float64 rotation, t: (3,) metres."""

    R: np.ndarray
    t: np.ndarray
    scale: float = 1.0

    def apply_points(self, p: np.ndarray) -> np.ndarray:
        """(N, 3) points in the estimate world -> (N, 3) in the GT world."""
        return self.scale * np.asarray(p, dtype=np.float64) @ self.R.T + self.t


def umeyama(src: np.ndarray, dst: np.ndarray, with_scale: bool = True) -> Sim3:
    """Least-squares Sim(3) (or SE(3) if not `with_scale`) with dst ~ s R src + t.

    src, dst: (N, 3) corresponding points, N >= 1 (N >= 3 non-collinear for a
    unique rotation). Umeyama 1991, with the reflection fix. Returns Sim3.
    """
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    if src.shape != dst.shape or src.ndim != 2 or src.shape[1] != 3 or len(src) == 0:
        raise ValueError(f"umeyama needs two (N, 3) arrays of equal shape, got {src.shape} and {dst.shape}")
    mu_s, mu_d = src.mean(0), dst.mean(0)
    xs, xd = src - mu_s, dst - mu_d
    cov = xd.T @ xs / len(src)
    U, D, Vt = np.linalg.svd(cov)
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[2, 2] = -1.0  # best proper rotation, not a reflection
    R = U @ S @ Vt
    var_s = (xs * xs).sum() / len(src)
    # A single point (or all points equal) has no scale information: keep 1.
    scale = float(np.trace(np.diag(D) @ S) / var_s) if with_scale and var_s > 1e-18 else 1.0
    t = mu_d - scale * R @ mu_s
    return Sim3(R=R, t=t, scale=scale)


def pose_sim3(est: np.ndarray, gt: np.ndarray) -> Sim3:
    """Sim(3) for comparing scenes (depth, meshes): rotation from the camera orientations,
    scale and translation from the centres given that rotation.

    est, gt: (N, 4, 4) T_world_cam. Umeyama on centres alone leaves the rotation about a
    short, nearly straight path undetermined (a 20 cm clip): a small trajectory error
    then turns the whole mesh. R is the chordal mean of R_gt_i R_est_i^T (SVD
    projection); s = sum <R x_i, y_i> / sum |x_i|^2 over centred centres (1 if they do
    not move); t = mean(y) - s R mean(x).
    """
    est, gt = np.asarray(est, np.float64), np.asarray(gt, np.float64)
    M = np.einsum("nij,nkj->ik", gt[:, :3, :3], est[:, :3, :3])  # sum R_gt R_est^T
    U, _, Vt = np.linalg.svd(M)
    S = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    R = U @ S @ Vt
    x, y = est[:, :3, 3], gt[:, :3, 3]
    xc, yc = x - x.mean(0), y - y.mean(0)
    var = float((xc * xc).sum())
    scale = float(((xc @ R.T) * yc).sum() / var) if var > 1e-18 else 1.0
    scale = scale if scale > 0 else 1.0
    return Sim3(R=R, t=y.mean(0) - scale * R @ x.mean(0), scale=scale)


@dataclass(frozen=True)
class AteResult:
    """ATE after alignment: `rmse_m` over (N,) per-frame `errors_m` (metres)."""

    rmse_m: float
    errors_m: np.ndarray
    alignment: Sim3


def ate(est: np.ndarray, gt: np.ndarray, with_scale: bool = True) -> AteResult:
    """Absolute trajectory error of camera centres after Umeyama alignment.

    est, gt: (N, 4, 4) T_world_cam, frame-by-frame correspondence.
    with_scale: Sim(3) alignment (monocular) if True, else SE(3).
    """
    p_est, p_gt = np.asarray(est)[:, :3, 3], np.asarray(gt)[:, :3, 3]
    align = umeyama(p_est, p_gt, with_scale=with_scale)
    err = np.linalg.norm(align.apply_points(p_est) - p_gt, axis=1)
    return AteResult(rmse_m=float(np.sqrt(np.mean(err**2))), errors_m=err, alignment=align)


@dataclass(frozen=True)
class RpeResult:
    """RMSE over consecutive pairs of the relative-pose error: translation (m), rotation (deg)."""

    trans_rmse_m: float
    rot_rmse_deg: float


def relative_errors(est: np.ndarray, gt: np.ndarray, delta: int = 1, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Per-pair relative-pose errors E_i = inv(Q_i^-1 Q_j) (P_i^-1 P_j), j = i + delta.

    est (P), gt (Q): (N, 4, 4) T_world_cam. `scale` multiplies estimate
    translations (the Sim(3) scale; rotations do not depend on it).
    Returns ((M,) translation norms in metres, (M,) rotation angles in radians), M = N - delta.
    """
    est = np.array(est, dtype=np.float64, copy=True)
    est[:, :3, 3] *= scale
    gt = np.asarray(gt, dtype=np.float64)
    rel_e = np.linalg.inv(est[:-delta]) @ est[delta:]
    rel_g = np.linalg.inv(gt[:-delta]) @ gt[delta:]
    E = np.linalg.inv(rel_g) @ rel_e
    trans = np.linalg.norm(E[:, :3, 3], axis=1)
    rot = rotation_angle(torch.from_numpy(E[:, :3, :3])).numpy()
    return trans, rot


def rpe(est: np.ndarray, gt: np.ndarray, delta: int = 1, scale: float = 1.0) -> RpeResult:
    """RPE RMSE over all pairs (i, i + delta); needs N > delta poses."""
    if len(est) != len(gt) or len(est) <= delta:
        raise ValueError(f"rpe needs two equally long trajectories longer than delta={delta}")
    trans, rot = relative_errors(est, gt, delta, scale)
    return RpeResult(
        trans_rmse_m=float(np.sqrt(np.mean(trans**2))),
        rot_rmse_deg=float(np.degrees(np.sqrt(np.mean(rot**2)))),
    )
