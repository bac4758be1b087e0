"""Sparse local bundle adjustment (scipy least squares, Huber loss) over recent camera poses
and the landmarks they see: the reference `test_schur_ba.py` checks the frontend's
`schur_ba.bundle_adjust_schur` against (the same problem, solved 7-9x slower). The oldest
`n_fixed` poses stay put: they fix the gauge and the scale, which the neural map has already
committed to."""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import lil_matrix

from nicer_stream.frontend.schur_ba import inlier_rms, reprojection
from nicer_stream.geometry.se3 import so3_exp_np as so3_exp
from nicer_stream.types import Intrinsics


def _residuals(params, n_free, fixed_cw, n_pts, cam, pt, uv, intr):
    """Reprojection errors (2M,) of all observations; free poses as (rvec, tvec) of T_cam_world."""
    free = params[: 6 * n_free].reshape(n_free, 6)
    X = params[6 * n_free:].reshape(n_pts, 3)
    R = np.concatenate([fixed_cw[:, :3, :3], so3_exp(free[:, :3])])
    t = np.concatenate([fixed_cw[:, :3, 3], free[:, 3:]])
    return reprojection(R, t, X, cam, pt, uv, intr)[1].ravel()


def bundle_adjust(poses: list[np.ndarray], n_fixed: int, points: np.ndarray, cam: np.ndarray, pt: np.ndarray,
                  uv: np.ndarray, intr: Intrinsics, huber_px: float = 2.0, max_nfev: int = 15):
    """Refine T_world_cam `poses` (list of (4, 4), the first `n_fixed` held) and world `points`
    (P, 3) from observations: camera ids `cam` (M,), point ids `pt` (M,), pixels `uv` (M, 2).
    Returns (poses, points, final RMS reprojection error in pixels over inlier observations)."""
    import cv2

    cw = np.stack([np.linalg.inv(T) for T in poses])
    n_free = len(poses) - n_fixed
    x0 = [np.concatenate([cv2.Rodrigues(T[:3, :3])[0][:, 0], T[:3, 3]]) for T in cw[n_fixed:]]
    params = np.concatenate([np.concatenate(x0) if x0 else np.zeros(0), points.ravel()])
    m = len(cam)
    sparsity = lil_matrix((2 * m, len(params)), dtype=np.int8)
    rows = np.arange(m)
    for k in range(6):
        sel = cam >= n_fixed
        for r2 in (0, 1):
            sparsity[2 * rows[sel] + r2, 6 * (cam[sel] - n_fixed) + k] = 1
    for k in range(3):
        for r2 in (0, 1):
            sparsity[2 * rows + r2, 6 * n_free + 3 * pt + k] = 1
    args = (n_free, cw[:n_fixed], len(points), cam, pt, uv, intr)
    res = least_squares(_residuals, params, jac_sparsity=sparsity, loss="huber", f_scale=huber_px,
                        max_nfev=max_nfev, x_scale="jac", method="trf", args=args)
    free = res.x[: 6 * n_free].reshape(n_free, 6)
    out = list(poses[:n_fixed])
    for f in free:
        T_cw = np.eye(4)
        T_cw[:3, :3], T_cw[:3, 3] = so3_exp(f[None, :3])[0], f[3:]
        out.append(np.linalg.inv(T_cw))
    return out, res.x[6 * n_free:].reshape(-1, 3), inlier_rms(res.fun.reshape(-1, 2), huber_px)
