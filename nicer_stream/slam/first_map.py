"""The map at the start: the metric scale from the first frame's depth prior, the scene bound and
the scene from its initial sphere, with the mapper and tracker that optimise it."""
from __future__ import annotations

import numpy as np
import torch

from nicer_stream.config import SlamConfig
from nicer_stream.mapping.depth_shift import shift_from_normals
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mapping.mapper import Mapper
from nicer_stream.model.bound import SceneBound
from nicer_stream.model.bound_estimate import bound_around, bound_from_config, bound_from_depth
from nicer_stream.model.geometry import initial_sphere
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from nicer_stream.slam.two_view import TwoView
from nicer_stream.tracking.tracker import Tracker


def first_scale_shift(mf: MapFrame, median_m: float) -> tuple[float, float]:
    """(w, q) of the first frame's depth prior (prior = w * depth + q): q from the normal
    prior's agreement (0 without one), w so that the median depth is `median_m` metres."""
    q = 0.0
    if mf.normal_prior is not None:
        q = shift_from_normals(mf.depth_prior.cpu().numpy(), mf.normal_prior.cpu().numpy(), mf.intr)
    valid = mf.depth_prior[mf.depth_prior > q]
    return float((valid - q).median()) / median_m, q


def start_scale(cfg: SlamConfig, first: MapFrame, second: MapFrame | None,
                view: TwoView | None) -> tuple[float, float] | None:
    """The scale rule (w, q) of the first frame's prior: the two-view fit's (which also fixes both
    frames' (w, q)), else, with an automatic bound, the first frame's own; None without a prior."""
    if view is not None:
        first.depth_scale_shift = view.first_scale_shift
        second.depth_scale_shift = view.second_scale_shift
        return view.first_scale_shift
    if first.depth_prior is not None and cfg.bound.mode == "auto":
        return first_scale_shift(first, cfg.loss.first_depth_median_m)
    return None


def start_bound(cfg: SlamConfig, first: MapFrame, view: TwoView | None, points: np.ndarray | None,
                scale_rule: tuple[float, float] | None) -> SceneBound:
    """The scene bound: around the first frame's prior depth at the scale rule, else around the
    frontend's triangulated `points` (M, 3) and the two cameras, else from the configuration."""
    if scale_rule is not None and cfg.bound.mode == "auto":
        w, q = scale_rule
        depth_m = ((first.depth_prior - q) / w).clamp_min(0).cpu().numpy()
        return bound_from_depth(depth_m, first.intr, np.eye(4), cfg.bound)
    if points is not None and cfg.bound.mode == "auto":
        cams = np.stack([np.zeros(3), view.T_world_second[:3, 3]])
        return bound_around(np.concatenate([points, cams]), cams, cfg.bound, "landmarks")
    return bound_from_config(cfg.bound)


def new_map(cfg: SlamConfig, bound: SceneBound, device: torch.device
            ) -> tuple[SceneModel, BetaField, Mapper, Tracker]:
    """The scene (its geometry the initial sphere around the first camera at the origin), the
    beta field, and the mapper and tracker over them."""
    model = SceneModel(cfg.model, bound).to(device)
    camera = bound.normalise(torch.zeros(1, 3, device=device))[0]
    model.geometry.set_sphere(*initial_sphere(cfg.model.sphere_centre, camera, cfg.model.sphere_radius,
                                              cfg.loss.first_depth_median_m / bound.half_extent))
    beta = BetaField(cfg.render).to(device)
    return model, beta, Mapper(model, beta, cfg, cfg.seed), Tracker(model, beta, cfg.tracking, cfg.render, cfg.seed)
