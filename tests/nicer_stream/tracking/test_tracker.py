"""The tracker recovers a perturbed pose against a map fitted with GT poses (synthetic scene)."""
from dataclasses import replace

import numpy as np
import torch

from nicer_stream.config import load
from nicer_stream.geometry.se3 import invert, rotation_angle, se3_exp
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mapping.mapper import Mapper
from nicer_stream.model.bound import SceneBound
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from nicer_stream.tracking.tracker import Tracker
from sources import open_source
from sources.base import SourceOptions


def test_tracker_recovers_perturbed_pose(tiny_config):
    torch.manual_seed(0)
    cfg = load("fast", tiny_config)
    cfg = replace(cfg, model=replace(cfg.model, color_levels=6, color_res_max=128, color_log2_table=15,
                                     fine_levels=3, fine_res_min=24, fine_res_max=48),
                  mapping=replace(cfg.mapping, rays=512, fine_start=0.2, ba_start=0.6),
                  tracking=replace(cfg.tracking, iters=40, rays=256, lr=5e-3),
                  render=replace(cfg.render, beta_mode="fixed", beta_fixed=0.02))
    frames = list(open_source("synthetic:room?frames=24", SourceOptions(max_side=64, stride=3)))
    mfs = [MapFrame.from_frame(f.without_ground_truth(), None, torch.device("cpu")) for f in frames]
    poses = {f.index: torch.tensor(f.gt_pose, dtype=torch.float32) for f in frames}
    centre = np.stack([f.gt_pose[:3, 3] for f in frames]).mean(0)
    model = SceneModel(cfg.model, SceneBound(tuple(centre), 3.0, "config"))
    beta = BetaField(cfg.render)
    Mapper(model, beta, cfg).optimise(mfs, poses, 250)

    target = frames[4]
    T_gt = poses[target.index]
    delta = se3_exp(torch.tensor([0.03, -0.02, 0.02, 0.02, -0.015, 0.01]))  # ~4 cm, ~1.5 deg
    T_init = T_gt @ delta
    res = Tracker(model, beta, cfg.tracking, cfg.render).track(mfs[4], T_init)

    def err(T):
        d = invert(T_gt) @ T
        return float(d[:3, 3].norm()), float(rotation_angle(d[:3, :3]))

    t0, r0 = err(T_init)
    t1, r1 = err(res.T_world_cam)
    assert res.loss <= res.initial_loss
    assert t1 < 0.5 * t0, (t0, t1)
    assert r1 < 0.7 * r0, (r0, r1)


def test_observed_mask_keeps_rays_ending_in_mapped_voxels():
    """Inside the initial sphere every ray ends at radius 0.9: only those ending in the
    counted half-space (x < 0) are kept; with nothing counted, all rays are used."""
    cfg = load("fast")
    model = SceneModel(replace(cfg.model, color_levels=4, color_res_max=64, color_log2_table=12),
                       SceneBound((0.0, 0.0, 0.0), 2.0, "config"))
    beta = BetaField(cfg.render)
    tracker = Tracker(model, beta, replace(cfg.tracking, min_count=100.0), cfg.render)
    from nicer_stream.render.renderer import RayBatch, render_rays

    dirs = torch.nn.functional.normalize(torch.randn(64, 3), dim=-1)
    dirs = dirs[dirs[:, 0].abs() > 0.2]
    rays = RayBatch(torch.zeros_like(dirs), dirs, torch.ones(len(dirs)))
    with torch.no_grad():
        out = render_rays(model, beta, rays, cfg.render, jitter=False)
    assert tracker._observed(rays, out) is None  # nothing mapped yet: no mask
    n = cfg.render.beta_voxels
    beta.counts.view(n, n, n)[: n // 2] = 1000.0  # voxel index i*n*n + ...: first axis is x
    mask = tracker._observed(rays, out)
    assert torch.equal(mask, dirs[:, 0] < 0)
