"""Frames whose exposure differs: the mapping objective with the mapper's per-frame affine
brightness recovers each frame's gain and bias relative to the first (the gauge); the mapper
registers, optimises and keeps them across calls."""
import math
import random
from dataclasses import replace

import torch

from nicer_stream.config import LossConfig, load
from nicer_stream.losses import total_loss
from nicer_stream.losses.brightness import apply_brightness
from nicer_stream.mapping.batched_objective import FrameStack, mapping_terms_batched
from nicer_stream.mapping.exposure import FrameExposures
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mapping.mapper import Mapper
from nicer_stream.mapping.ray_sampling import batch_rays
from nicer_stream.model.bound import SceneBound
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from nicer_stream.render.renderer import RenderOutput
from sources import open_source
from sources.base import SourceOptions

GAINS = (1.0, 0.75, 0.9, 0.7, 0.85, 0.8)
BIASES = (0.0, 0.06, -0.02, 0.08, 0.03, 0.0)


def _room(n: int, side: int):
    frames = list(open_source(f"synthetic:room?frames={3 * n}", SourceOptions(max_side=side, stride=3)))
    poses = {f.index: torch.tensor(f.gt_pose, dtype=torch.float32) for f in frames}
    return frames, poses


def test_the_objective_recovers_each_frames_brightness_against_the_true_radiance():
    """The render is the frames' own radiance (what a converged map gives) at depth from the
    scene: the RGB and warping terms with the brightness prior fit (a, b) of frames 1-5 to the
    exposures applied to them, frame 0 holding the gauge."""
    frames, poses = _room(6, 40)
    mfs, radiance = [], []
    for f, g, b in zip(frames, GAINS, BIASES):
        mf = MapFrame.from_frame(f.without_ground_truth(), None, torch.device("cpu"))
        radiance.append(mf.rgb.reshape(-1, 3))
        mf.rgb = apply_brightness(mf.rgb, torch.tensor([math.log(g), b]))
        assert float(mf.rgb.max()) <= 1.0
        mfs.append(mf)
    depth = [torch.as_tensor(f.gt_depth, dtype=torch.float32).reshape(-1) for f in frames]
    cfg = LossConfig(affine_brightness=True, huber_delta=0.02)
    stack, ex = FrameStack.build(mfs), FrameExposures(lr=0.02)
    gen, rng = torch.Generator().manual_seed(0), random.Random(0)
    for _ in range(150):
        rays, layout = batch_rays(mfs, [poses[f.index] for f in mfs], 6 * 128, gen)
        n = rays.origins.shape[0]
        out = RenderOutput(rgb=torch.cat([r[fr.pix] for r, fr in zip(radiance, layout)]),
                           depth=torch.cat([d[fr.pix] for d, fr in zip(depth, layout)]),
                           ray_dist=torch.zeros(n), normal=torch.zeros(n, 3), opacity=torch.ones(n),
                           points=torch.zeros(n, 3), sdf_grad=torch.zeros(0, 3))
        terms = mapping_terms_batched(out, layout, stack, cfg, None, None, rng, ex.rows([f.index for f in mfs]))
        terms.eikonal = None
        total_loss(terms, cfg.weights).backward()
        ex.step()
    got = [ex.value(f.index) for f in mfs]
    print("got", [(round(math.exp(a), 3), round(b, 3)) for a, b in got])
    assert ex.reference == mfs[0].index and got[0] == (0.0, 0.0)
    for (a, b), g, b_true in zip(got[1:], GAINS[1:], BIASES[1:]):
        assert abs(math.exp(a) - g) < 0.02 and abs(b - b_true) < 0.01, (math.exp(a), g, b, b_true)


def test_the_mapper_optimises_brightness_across_calls_and_holds_the_gauge(tiny_config):
    cfg = load("fast", tiny_config)
    cfg = replace(cfg, loss=replace(cfg.loss, affine_brightness=True), mapping=replace(cfg.mapping, rays=64))
    frames, poses = _room(3, 24)
    mfs = [MapFrame.from_frame(f.without_ground_truth(), None, torch.device("cpu")) for f in frames]
    model = SceneModel(cfg.model, SceneBound(tuple(frames[0].gt_pose[:3, 3]), 3.0, "config"))
    mapper = Mapper(model, BetaField(cfg.render), cfg)
    stats = mapper.optimise(mfs, poses, 3)
    assert "brightness" in stats.terms
    first = {f.index: mapper.exposures.value(f.index) for f in mfs}
    assert first[mfs[0].index] == (0.0, 0.0) and all(v != (0.0, 0.0) for v in list(first.values())[1:])
    mapper.optimise(mfs[1:], poses, 2)  # a window without the reference: its gauge stays
    assert mapper.exposures.reference == mfs[0].index
    assert all(mapper.exposures.value(f.index) != first[f.index] for f in mfs[1:])
    off = Mapper(model, BetaField(cfg.render), replace(cfg, loss=replace(cfg.loss, affine_brightness=False)))
    assert off.exposures is None and "brightness" not in off.optimise(mfs, poses, 1).terms
