"""Gauss-Newton pose steps for photometric tracking (pure functions).

The rendered colour of a ray depends on the pose only through the ray's origin o and unit
direction d (world frame). For the right-multiplicative update T' = T @ exp(xi), xi = (rho, phi)
in the camera frame (geometry/se3.py), to first order: o' = o + R rho and d' = d + R (phi x d_c),
with d_c = R^T d the camera-frame direction. So one backward pass per colour channel to (o, d)
gives every ray's (3 x 6) Jacobian, and a 6 x 6 normal-equation solve gives the step that
Adam would need tens of iterations to take.
"""
from __future__ import annotations

import torch


def ray_twist_jacobian(g_o: torch.Tensor, g_d: torch.Tensor, dirs: torch.Tensor, R: torch.Tensor) -> torch.Tensor:
    """(..., N, 3) gradients w.r.t. ray origins and unit directions (world), (N, 3) unit
    world directions, (3, 3) camera-to-world rotation -> (..., N, 6) d value / d xi at xi = 0."""
    d_cam = dirs @ R  # rows: R^T d
    j_rho = g_o @ R  # g_o . (R rho)
    # g_d . (R (phi x d_c)) = (R^T g_d) . (phi x d_c) = phi . (d_c x R^T g_d)
    j_phi = torch.linalg.cross(d_cam.expand_as(g_d), g_d @ R, dim=-1)
    return torch.cat([j_rho, j_phi], dim=-1)


def damped_step(J: torch.Tensor, r: torch.Tensor, w: torch.Tensor, damping: float) -> torch.Tensor:
    """Levenberg-Marquardt step minimising sum w (r + J xi)^2 + damping * xi^T diag(H) xi.

    J: (M, 6), r: (M,), w: (M,) -> xi (6,). Solved in float64 (6 x 6: free)."""
    Jw = (J * w[:, None]).double()
    H = Jw.T @ J.double()
    b = Jw.T @ r.double()
    H = H + damping * torch.diag(H.diagonal().clamp_min(1e-12))
    return -torch.linalg.solve(H, b).to(J.dtype)
