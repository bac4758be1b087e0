"""Bundle adjustment by Levenberg-Marquardt on the Schur complement (pure numpy).

The same problem as the scipy least-squares reference its test compares it with
(`tests/nicer_stream/frontend/local_ba_reference.py`): poses and points from pixel observations under a Huber loss, the
first `n_fixed` poses held. Each point couples only to the cameras that see it, so its 3x3
block is eliminated first and the step solves a (6F, 6F) system for the F free cameras. On a
15-camera window with 23k observations it converged in 0.8-1.1 s where scipy's sparse trust
region took 7.4-8.1 s to a higher cost (docs/performance.md): too slow to run every frame.

Cameras are T_cam_world = (R, t), updated on the left: R <- exp(w) R, t <- exp(w) t + v.
"""
from __future__ import annotations

import numpy as np
import torch

from nicer_stream.geometry import se3
from nicer_stream.types import Intrinsics


def _skew(p: np.ndarray) -> np.ndarray:
    """(M, 3) -> (M, 3, 3) cross-product matrices [p]x (numpy view of `geometry.se3.skew`)."""
    return se3.skew(torch.from_numpy(p)).numpy()


def reprojection(R, t, X, cam, pt, uv, intr):
    """Camera-frame points (M, 3) and reprojection residuals (M, 2) of every observation:
    cameras T_cam_world (R (N, 3, 3), t (N, 3)), points X (P, 3), ids cam, pt (M,), pixels uv."""
    p = np.einsum("mij,mj->mi", R[cam], X[pt]) + t[cam]
    z = np.maximum(p[:, 2], 1e-6)
    r = np.stack([intr.fx * p[:, 0] / z + intr.cx, intr.fy * p[:, 1] / z + intr.cy], -1) - uv
    return p, r


def _gram(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A^T B for tall (K, n) float64 arrays, through torch's BLAS and thread pool: numpy's
    OpenBLAS keeps threads of its own, and next to torch's (or another process) on two
    cores this one product measured 3 ms or 300 ms from run to run."""
    return (torch.from_numpy(A).T @ torch.from_numpy(B)).numpy()


def inlier_rms(r: np.ndarray, huber_px: float) -> float:
    """RMS pixel error of the residuals r (M, 2) within 3 `huber_px` (NaN when none are)."""
    err = np.linalg.norm(r, axis=1)
    inl = err < 3 * huber_px
    return float(np.sqrt(np.mean(err[inl] ** 2))) if inl.any() else float("nan")


def huber_cost(r: np.ndarray, k: float) -> float:
    """Sum over observations of the Huber loss of the residual norm (M, 2) -> scalar, scale k px."""
    e = np.linalg.norm(r, axis=1)
    return float(np.where(e <= k, 0.5 * e**2, k * (e - 0.5 * k)).sum())


def bundle_adjust_schur(poses: list[np.ndarray], n_fixed: int, points: np.ndarray, cam: np.ndarray, pt: np.ndarray,
                        uv: np.ndarray, intr: Intrinsics, huber_px: float = 2.0, max_iters: int = 30,
                        tol: float = 1e-6):
    """Refine T_world_cam `poses` (list of (4, 4), the first `n_fixed` held) and world `points`
    (P, 3) from observations: camera ids `cam` (M,), point ids `pt` (M,), pixels `uv` (M, 2);
    one observation per (camera, point). Stops after `max_iters` iterations or when the cost
    falls by less than `tol` relatively. Returns (poses, points, RMS reprojection error in
    pixels over the observations within 3 `huber_px`), as the reference."""
    cw = np.stack([np.linalg.inv(T) for T in poses])
    R, t, X = cw[:, :3, :3].copy(), cw[:, :3, 3].copy(), points.astype(np.float64).copy()
    n_cam, n_pts, n_free = len(poses), len(points), len(poses) - n_fixed
    free = cam >= n_fixed
    lam = 1e-3
    _, r = reprojection(R, t, X, cam, pt, uv, intr)
    cost = huber_cost(r, huber_px)
    for _ in range(max_iters if n_free > 0 or n_pts > 0 else 0):
        p, r = reprojection(R, t, X, cam, pt, uv, intr)
        e = np.linalg.norm(r, axis=1)
        w = np.where(e <= huber_px, 1.0, huber_px / np.maximum(e, 1e-12))  # IRLS weights of the Huber loss
        z = np.maximum(p[:, 2], 1e-6)
        Jp = np.zeros((len(p), 2, 3))  # d pixel / d camera-frame point
        Jp[:, 0, 0], Jp[:, 0, 2] = intr.fx / z, -intr.fx * p[:, 0] / z**2
        Jp[:, 1, 1], Jp[:, 1, 2] = intr.fy / z, -intr.fy * p[:, 1] / z**2
        Jc = np.concatenate([Jp @ -_skew(p), Jp], axis=2)  # (M, 2, 6): rotation, then translation
        Jx = Jp @ R[cam]  # (M, 2, 3)
        wr = w[:, None] * r
        Hpp = np.zeros((n_pts, 3, 3))
        np.add.at(Hpp, pt, np.einsum("mki,m,mkj->mij", Jx, w, Jx))
        gp = np.zeros((n_pts, 3))
        np.add.at(gp, pt, np.einsum("mki,mk->mi", Jx, wr))
        Hcc = np.zeros((n_cam, 6, 6))
        np.add.at(Hcc, cam, np.einsum("mki,m,mkj->mij", Jc, w, Jc))
        gc = np.zeros((n_cam, 6))
        np.add.at(gc, cam, np.einsum("mki,mk->mi", Jc, wr))
        # V[p, :, 6c:6c+6] = J_x^T w J_c of observation (c, p), free cameras only: the point-camera
        # blocks, laid out so that the Schur product below is one GEMM without copies.
        V = np.zeros((n_pts, 3, 6 * n_free))
        cols = 6 * (cam[free] - n_fixed)[:, None] + np.arange(6)
        V[pt[free][:, None], :, cols] = np.einsum("mki,m,mkj->mji", Jx[free], w[free], Jc[free])
        while True:
            Hpp_d = Hpp + lam * (np.diagonal(Hpp, axis1=1, axis2=2)[..., None] * np.eye(3) + 1e-9 * np.eye(3))
            Binv = np.linalg.inv(Hpp_d)
            if n_free:
                Hf = Hcc[n_fixed:]
                Hf_d = Hf + lam * np.diagonal(Hf, axis1=1, axis2=2)[..., None] * np.eye(6)
                S = np.zeros((6 * n_free, 6 * n_free))
                for c in range(n_free):
                    S[6 * c:6 * c + 6, 6 * c:6 * c + 6] = Hf_d[c]
                BV = Binv @ V  # (P, 3, 6F)
                S -= _gram(V.reshape(-1, 6 * n_free), BV.reshape(-1, 6 * n_free))
                b = -gc[n_fixed:].reshape(-1) + np.einsum("pji,pj->i", BV, gp)
                dc = np.linalg.solve(S + 1e-12 * np.eye(len(S)), b)
                dX = np.einsum("pij,pj->pi", Binv, -gp - V @ dc)
            else:
                dc = np.zeros(0)
                dX = np.einsum("pij,pj->pi", Binv, -gp)
            d = dc.reshape(n_free, 6)
            Rn, tn = R.copy(), t.copy()
            if n_free:
                E = se3.so3_exp_np(d[:, :3])
                Rn[n_fixed:] = E @ R[n_fixed:]
                tn[n_fixed:] = np.einsum("nij,nj->ni", E, t[n_fixed:]) + d[:, 3:]
            Xn = X + dX
            _, rn = reprojection(Rn, tn, Xn, cam, pt, uv, intr)
            new_cost = huber_cost(rn, huber_px)
            if new_cost < cost:
                break
            lam *= 10.0
            if lam > 1e8:
                break
        if new_cost >= cost:
            break
        R, t, X = Rn, tn, Xn
        done = cost - new_cost < tol * cost
        cost, lam = new_cost, max(lam / 10.0, 1e-7)
        if done:
            break
    out = []
    for k in range(n_cam):
        T_cw = np.eye(4)
        T_cw[:3, :3], T_cw[:3, 3] = R[k], t[k]
        out.append(np.asarray(poses[k], np.float64) if k < n_fixed else np.linalg.inv(T_cw))
    return out, X, inlier_rms(reprojection(R, t, X, cam, pt, uv, intr)[1], huber_px)
