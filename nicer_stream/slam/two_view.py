"""Two-view initialisation: the second camera and both depth priors' scale and shift.

A relative depth prior is `w * depth + q`. From the first frame alone the shift q can
only be guessed (the paper takes 0; `depth_shift` reads it off the normal prior, to
~2% of the median depth), and a wrong q bends the whole map: depth becomes
`a * true + b` (Replica clip: b ~ 13 cm), which no similarity alignment removes.
With a second frame far enough away, the flow between the two gives the relative pose
(essential matrix, up to scale) and a triangulated depth for every flow pixel; a robust
affine fit of each prior to it gives (w, q) from geometry. The metric scale stays a
convention: the first frame's median depth is `median_m` metres.

Measured on Replica frames 0/10 (10 cm baseline, 320 px), shift error relative to the
prior's median: oracle flow 0.08%, DIS flow 8.6% (worse than the normal prior's 2.2%: so
little parallax needs accurate flow); synthetic room frames 0/10 (25 cm): oracle 0.7%, DIS 1.6%
of the true shift.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import torch

from nicer_stream.geometry.camera import in_image, pixel_grid, project_world
from nicer_stream.geometry.pose_estimation import essential_pose
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mapping.prior_alignment import align_frame_prior, robust_affine_fit
from nicer_stream.types import Intrinsics

log = logging.getLogger(__name__)

# A fitted (w, q) may put at most this fraction of a prior's pixels at non-positive depth: a
# correct fit puts none there (docs/decisions.md, "The two-view start's checks").
MAX_BEHIND = 0.01
# The two-view fit's depth of the first frame may differ from its normal prior's start by at most
# this fraction of the median: beyond it the flow, not the normals, is wrong (same entry).
MAX_DISAGREEMENT = 0.04


@dataclass(frozen=True)
class TwoView:
    """T_world_cam (4, 4) float64 of the second frame (world = first camera), and each
    frame's prior (w, q) with prior = w * z_metres + q; inliers of the essential matrix."""

    T_world_second: np.ndarray
    first_scale_shift: tuple[float, float]
    second_scale_shift: tuple[float, float] | None
    inliers: int


def relative_pose(first: MapFrame, second: MapFrame, max_points: int = 5000, thresh_px: float = 1.0,
                  seed: int = 0) -> tuple[np.ndarray, int] | None:
    """T_world_cam (4, 4) float64 of `second` with `first` at the identity and a unit
    baseline, from `first`'s flow to it by the essential matrix; with the inlier count.
    None without a flow or with fewer than 100 inliers."""
    if second.index not in first.flows:
        return None
    flow, valid = first.flows[second.index]
    ids = valid.reshape(-1).nonzero()[:, 0].cpu().numpy()
    if len(ids) < 100:
        return None
    ids = np.random.default_rng(seed).permutation(ids)[:max_points]
    uv0 = pixel_grid(first.intr).reshape(-1, 2).cpu().numpy()[ids].astype(np.float64)
    uv1 = uv0 + flow.reshape(-1, 2).cpu().numpy()[ids].astype(np.float64)
    rel = essential_pose(uv0, uv1, first.intr, thresh_px, 100)
    return None if rel is None else (rel[0], rel[1])


def _known(prior: torch.Tensor) -> torch.Tensor:
    """A prior's known values (positive, finite), flattened, float64."""
    return prior[(prior > 0) & torch.isfinite(prior)].double()


def behind_fraction(prior: torch.Tensor, wq: tuple[float, float]) -> float:
    """Fraction of a prior's known pixels (positive, finite) whose depth (prior - q) / w is not
    positive under (w, q): a fit no real depth map can have."""
    w, q = wq
    known = _known(prior)
    return float(((known - q) / w <= 0).double().mean()) if known.numel() else 1.0


def target_disagreement(prior: torch.Tensor, a: tuple[float, float], b: tuple[float, float]) -> float:
    """Median |depth_a - depth_b| over a prior's known pixels, relative to depth_b's median, of
    the depths (prior - q) / w under two fits a and b."""
    known = _known(prior)
    da, db = (known - a[1]) / a[0], (known - b[1]) / b[0]
    return float((da - db).abs().median() / db.median().abs().clamp_min(1e-12))


def two_view_init(first: MapFrame, second: MapFrame, median_m: float,
                  max_behind: float = MAX_BEHIND, reference: tuple[float, float] | None = None,
                  max_disagreement: float = MAX_DISAGREEMENT) -> TwoView | None:
    """The second pose and both priors' (w, q), at the scale where `first`'s median aligned
    depth is `median_m`; None when the geometry is too weak (no flow, < 100 essential-matrix
    inliers, a failed or non-positive fit, or a fit that puts more than `max_behind` of the
    first prior's pixels at non-positive depth, or, given a `reference` (w, q) of the first
    prior at the same median (its normal prior's start), a depth that differs from the
    reference's by more than `max_disagreement` of its median). A second fit behind the camera
    is dropped (its (w, q) then comes from the mapping's per-iteration fit)."""
    rel = relative_pose(first, second)
    if rel is None or first.depth_prior is None:
        return None
    T1 = torch.as_tensor(rel[0])
    wq = align_frame_prior(first, second, torch.eye(4, dtype=torch.float64), T1)
    if wq is None or wq[0] <= 0:
        return None
    w, q = wq
    behind = behind_fraction(first.depth_prior, wq)
    if behind > max_behind:
        log.warning("two-view start rejected: its prior fit puts %.0f%% of frame %d's depth at or behind the camera",
                    100 * behind, first.index)
        return None
    prior = first.depth_prior[first.depth_prior > q].double()
    if prior.numel() < 100:
        return None
    s = median_m / float(((prior - q) / w).median())  # unit-baseline depth -> metres
    if reference is not None:
        off = target_disagreement(first.depth_prior, (w / s, q), reference)
        if off > max_disagreement:
            log.warning("two-view start rejected: its depth of frame %d differs from the normal prior's start by "
                        "%.0f%% of the median (the flow is too coarse for the shift)", first.index, 100 * off)
            return None
    T1 = T1.numpy().copy()
    T1[:3, 3] *= s
    second_wq = align_frame_prior(second, first, torch.as_tensor(T1), torch.eye(4, dtype=torch.float64))
    ok = second_wq is not None and second_wq[0] > 0 and behind_fraction(second.depth_prior, second_wq) <= max_behind
    second_wq = second_wq if ok else None
    return TwoView(T1, (w / s, q), second_wq, rel[1])


def prior_fit_to_points(frame: MapFrame, T_world_cam: np.ndarray, points: np.ndarray,
                        max_behind: float = MAX_BEHIND) -> tuple[float, float] | None:
    """(w, q) of `frame`'s depth prior (prior = w * z + q) fitted robustly to the z-depths of
    world points (P, 3) seen at T_world_cam (4, 4), each against the prior at its nearest pixel;
    None with fewer than 20 points on known prior pixels, a non-positive w, or a fit that puts
    more than `max_behind` of the prior's pixels at non-positive depth."""
    if frame.depth_prior is None or len(points) == 0:
        return None
    uv, z = project_world(T_world_cam, np.asarray(points, np.float64), frame.intr)
    seen = (z > 0) & in_image(uv, frame.intr)
    u, v = np.round(uv[seen]).astype(int).clip(0, [frame.intr.width - 1, frame.intr.height - 1]).T
    prior = frame.depth_prior.detach().double().cpu().numpy()[v, u]
    known = (prior > 0) & np.isfinite(prior)
    wq = robust_affine_fit(torch.as_tensor(prior[known]), torch.as_tensor(z[seen][known]))
    if wq is None or wq[0] <= 0 or behind_fraction(frame.depth_prior, wq) > max_behind:
        return None
    return wq


def two_view_from_tracks(first: MapFrame, second: MapFrame, T_world_second: np.ndarray, points: np.ndarray,
                         inliers: int) -> TwoView | None:
    """A start with depth priors from the frontend's two views (`ClassicalFrontend.two_view`:
    second pose T_world_cam (4, 4), triangulated points (P, 3) world, at its scale): each
    prior's (w, q) fitted to the points' depths in its frame (`prior_fit_to_points`). Why: the
    frontend's tracks on the source's full image, adjusted (`start_ba`), place the second view
    far better than dense flow at the map's size (Replica frames 0/10: 0.02 degrees of rotation
    off GT), and the priors then share the trajectory's scale from the first mapping on. None
    where the first prior cannot be fitted; a second that cannot keeps the per-iteration fit."""
    first_wq = prior_fit_to_points(first, np.eye(4), points)
    if first_wq is None:
        return None
    return TwoView(np.asarray(T_world_second, np.float64), first_wq,
                   prior_fit_to_points(second, T_world_second, points), inliers)
