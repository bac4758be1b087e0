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


def frontend_disagreement(T: torch.Tensor, T_front: torch.Tensor, T_prev: torch.Tensor, depth: float,
                          cfg) -> str | None:
    """A reason string when the photometric pose `T` and the frontend's `T_front` disagree by
    more than `cfg` (FrontendConfig) allows. The translation bound scales with the scene (a
    fraction of `depth`, the median depth of the frontend's landmarks) and with the frame's
    motion from `T_prev`, the previous frame's pose: the SLAM's unit of length is a convention."""
    delta = invert(T_front) @ T
    dist = float(delta[:3, 3].norm())
    motion = float((T_front[:3, 3] - T_prev[:3, 3]).norm())
    bound = max(cfg.max_disagreement_depth_frac * depth, cfg.max_disagreement_frac * motion)
    if dist > bound:
        return f"photometric pose {dist:.3g} from the frontend's (bound {bound:.3g}; unit: the map's)"
    ang = math.degrees(float(rotation_angle(delta[:3, :3])))
    if ang > cfg.max_disagreement_deg:
        return f"photometric pose rotated {ang:.2f} deg from the frontend's (bound {cfg.max_disagreement_deg} deg)"
    return None
