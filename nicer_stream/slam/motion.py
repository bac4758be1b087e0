"""Motion model and tracking-failure checks (pure functions)."""
from __future__ import annotations

import math

import torch

from nicer_stream.config import TrackingConfig
from nicer_stream.geometry.se3 import invert, rotation_angle


def predict_pose(history: list[torch.Tensor], mode: str) -> torch.Tensor:
    """Initial guess for the next T_world_cam from past poses: 'previous' or
    'constant_velocity' (T_prev @ T_prevprev^-1 @ T_prev, in the camera frame); 'flow'
    (whose PnP needs the map, see tracking.flow_init) falls back to the previous pose."""
    if mode not in ("previous", "constant_velocity", "flow"):
        raise ValueError(f"tracking init must be 'previous', 'constant_velocity' or 'flow', got {mode!r}")
    if mode in ("previous", "flow") or len(history) < 2:
        return history[-1].clone()
    prev, prevprev = history[-1], history[-2]
    return prev @ (invert(prevprev) @ prev)


def tracking_failure(T: torch.Tensor, T_pred: torch.Tensor, loss: float, recent_losses: list[float],
                     cfg: TrackingConfig) -> str | None:
    """A reason string when the tracked pose must not be trusted, else None."""
    if not torch.isfinite(T).all() or not math.isfinite(loss):
        return "non-finite pose or loss"
    delta = invert(T_pred) @ T
    jump = float(delta[:3, 3].norm())
    if jump > cfg.max_jump_m:
        return f"pose jumped {jump:.2f} m from the prediction"
    ang = math.degrees(float(rotation_angle(delta[:3, :3])))
    if ang > cfg.max_jump_deg:
        return f"pose rotated {ang:.1f} deg from the prediction"
    if len(recent_losses) >= 3:
        med = sorted(recent_losses)[len(recent_losses) // 2]
        if loss > cfg.loss_jump * med:
            return f"tracking loss {loss:.3f} is {loss / med:.1f}x the recent median"
    return None
