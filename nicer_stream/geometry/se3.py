"""SO(3)/SE(3) maths as pure torch functions (batched over leading dims).

Poses are 4x4 `T_a_b` matrices mapping points in frame b to frame a
(`T_world_cam`: camera-to-world). Twists are xi = (rho, phi) in R^6:
translation part first, rotation (axis-angle) second, with
T = exp(xi^) in SE(3). Quaternions are stored (qx, qy, qz, qw) as in TUM files.
The optimiser-facing update is right-multiplicative: T = T0 @ exp(xi),
so xi is a perturbation expressed in the camera frame.
"""
from __future__ import annotations

import numpy as np
import torch

_EPS = 1e-8


def skew(v: torch.Tensor) -> torch.Tensor:
    """(..., 3) -> (..., 3, 3) cross-product matrix [v]x."""
    x, y, z = v.unbind(-1)
    o = torch.zeros_like(x)
    return torch.stack([o, -z, y, z, o, -x, -y, x, o], dim=-1).reshape(*v.shape[:-1], 3, 3)


def _taylor_coeffs(theta2: torch.Tensor):
    """A = sin t / t, B = (1 - cos t)/t^2, C = (t - sin t)/t^3, safe at t -> 0."""
    small = theta2 < 1e-6
    t2 = torch.where(small, torch.ones_like(theta2), theta2)
    t = torch.sqrt(t2)
    a = torch.where(small, 1 - theta2 / 6, torch.sin(t) / t)
    b = torch.where(small, 0.5 - theta2 / 24, (1 - torch.cos(t)) / t2)
    c = torch.where(small, 1.0 / 6 - theta2 / 120, (t - torch.sin(t)) / (t2 * t))
    return a, b, c


def so3_exp_np(w: np.ndarray) -> np.ndarray:
    """numpy: (N, 3) rotation vectors -> (N, 3, 3) rotation matrices (Rodrigues, float64), for the
    frontend's bundle adjustment. Not through torch (`se3_exp`): its last-bit rounding differs and
    the adjustment's iterations carry that into the poses (0.4 mm on the synthetic room)."""
    th = np.linalg.norm(w, axis=1)[:, None, None]
    K = skew(torch.from_numpy(w / np.maximum(th[:, :, 0], 1e-12))).numpy()
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * (K @ K)


def so3_log(R: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3) rotation -> (..., 3) axis-angle with angle in [0, pi]."""
    q = matrix_to_quat(R)
    xyz, w = q[..., :3], q[..., 3:]
    n = xyz.norm(dim=-1, keepdim=True)
    # angle = 2 atan2(|xyz|, w); atan2 is well conditioned everywhere, including near pi.
    angle = 2 * torch.atan2(n, w)
    scale = torch.where(n < _EPS, 2.0 / w.clamp_min(_EPS), angle / n.clamp_min(_EPS))
    return xyz * scale


def se3_exp(xi: torch.Tensor) -> torch.Tensor:
    """(..., 6) twist (rho, phi) -> (..., 4, 4) pose."""
    rho, phi = xi[..., :3], xi[..., 3:]
    theta2 = (phi * phi).sum(-1)[..., None, None]
    a, b, c = _taylor_coeffs(theta2)
    K = skew(phi)
    eye = torch.eye(3, dtype=xi.dtype, device=xi.device).expand(K.shape)
    R = eye + a * K + b * (K @ K)
    V = eye + b * K + c * (K @ K)
    t = (V @ rho[..., None])[..., 0]
    return make_pose(R, t)


def se3_log(T: torch.Tensor) -> torch.Tensor:
    """(..., 4, 4) pose -> (..., 6) twist (rho, phi)."""
    R, t = T[..., :3, :3], T[..., :3, 3]
    phi = so3_log(R)
    theta2 = (phi * phi).sum(-1)[..., None, None]
    a, b, c = _taylor_coeffs(theta2)
    K = skew(phi)
    eye = torch.eye(3, dtype=T.dtype, device=T.device).expand(K.shape)
    V = eye + b * K + c * (K @ K)
    rho = torch.linalg.solve(V, t[..., None])[..., 0]
    return torch.cat([rho, phi], dim=-1)


def make_pose(R: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3) rotation and (..., 3) translation -> (..., 4, 4) pose."""
    T = torch.zeros(*R.shape[:-2], 4, 4, dtype=R.dtype, device=R.device)
    T[..., :3, :3] = R
    T[..., :3, 3] = t
    T[..., 3, 3] = 1.0
    return T


def invert(T: torch.Tensor) -> torch.Tensor:
    """Inverse of (..., 4, 4) rigid transforms, T_b_a from T_a_b."""
    R, t = T[..., :3, :3], T[..., :3, 3]
    Rt = R.transpose(-1, -2)
    return make_pose(Rt, -(Rt @ t[..., None])[..., 0])


def transform_points(T: torch.Tensor, p: torch.Tensor) -> torch.Tensor:
    """Apply (4, 4) T_a_b to (..., 3) points in frame b -> points in frame a."""
    return p @ T[:3, :3].transpose(0, 1) + T[:3, 3]


def quat_to_matrix(q: torch.Tensor) -> torch.Tensor:
    """(..., 4) quaternion (qx, qy, qz, qw), any norm -> (..., 3, 3) rotation."""
    q = q / q.norm(dim=-1, keepdim=True)
    x, y, z, w = q.unbind(-1)
    return torch.stack(
        [
            1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
            2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
            2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y),
        ],
        dim=-1,
    ).reshape(*q.shape[:-1], 3, 3)


def matrix_to_quat(R: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3) rotation -> (..., 4) unit quaternion (qx, qy, qz, qw) with qw >= 0."""
    m = R
    tr = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]
    # Four candidate solutions; pick the numerically largest denominator per matrix.
    cands = torch.stack(
        [
            torch.stack([m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1], 1 + tr], -1),
            torch.stack([1 + m[..., 0, 0] - m[..., 1, 1] - m[..., 2, 2], m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0], m[..., 2, 1] - m[..., 1, 2]], -1),
            torch.stack([m[..., 0, 1] + m[..., 1, 0], 1 - m[..., 0, 0] + m[..., 1, 1] - m[..., 2, 2], m[..., 1, 2] + m[..., 2, 1], m[..., 0, 2] - m[..., 2, 0]], -1),
            torch.stack([m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], 1 - m[..., 0, 0] - m[..., 1, 1] + m[..., 2, 2], m[..., 1, 0] - m[..., 0, 1]], -1),
        ],
        dim=-2,
    )
    diag = torch.stack([tr, m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]], -1)
    best = diag.argmax(-1)
    q = torch.gather(cands, -2, best[..., None, None].expand(*best.shape, 1, 4))[..., 0, :]
    q = q / q.norm(dim=-1, keepdim=True)
    return torch.where(q[..., 3:] < 0, -q, q)


def pose_from_tum(txyz_qxyzw: torch.Tensor) -> torch.Tensor:
    """(..., 7) `tx ty tz qx qy qz qw` -> (..., 4, 4) pose."""
    return make_pose(quat_to_matrix(txyz_qxyzw[..., 3:]), txyz_qxyzw[..., :3])


def pose_to_tum(T: torch.Tensor) -> torch.Tensor:
    """(..., 4, 4) pose -> (..., 7) `tx ty tz qx qy qz qw`."""
    return torch.cat([T[..., :3, 3], matrix_to_quat(T[..., :3, :3])], dim=-1)


def rotation_angle(R: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3) -> (...,) rotation angle in radians."""
    return so3_log(R).norm(dim=-1)
