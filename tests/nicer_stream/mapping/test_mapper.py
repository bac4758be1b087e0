"""Mapper: the stage schedule freezes what it says, with persistent gradient buffers; the
learning-rate schedule of a call."""
import math
from dataclasses import replace

import pytest
import torch

from nicer_stream.config import load
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mapping.mapper import Mapper
from nicer_stream.model.bound import SceneBound
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from sources import open_source
from sources.base import SourceOptions


def test_frozen_groups_stay_put_and_grad_buffers_persist(tmp_path, tiny_toml):
    path = tmp_path / "tiny.toml"
    path.write_text(tiny_toml)
    cfg = load("fast", path)
    cfg = replace(cfg, model=replace(cfg.model, color_levels=4, color_res_max=64, color_log2_table=12,
                                     fine_levels=2, fine_res_min=16, fine_res_max=24),
                  mapping=replace(cfg.mapping, rays=128, fine_start=0.5, ba_start=1.0),
                  render=replace(cfg.render, beta_mode="fixed", beta_fixed=0.02))
    frames = list(open_source("synthetic:room?frames=6", SourceOptions(max_side=32, stride=3)))
    mfs = [MapFrame.from_frame(f.without_ground_truth(), None, torch.device("cpu")) for f in frames]
    poses = {f.index: torch.tensor(f.gt_pose, dtype=torch.float32) for f in frames}
    torch.manual_seed(0)
    model = SceneModel(cfg.model, SceneBound(tuple(frames[0].gt_pose[:3, 3]), 3.0, "config"))
    mapper = Mapper(model, BetaField(cfg.render), cfg)
    coarse, fine, color = model.grid_tables()
    bufs = [t.grad for t in model.grid_tables()]
    before = [t.detach().clone() for t in model.grid_tables()]

    mapper.optimise(mfs, poses, 1, color_start=1.0)  # frac 0 < fine_start: coarse only
    assert not torch.equal(coarse.detach(), before[0])
    assert torch.equal(fine.detach(), before[1]) and torch.equal(color.detach(), before[2])
    assert all(t.grad is b for t, b in zip(model.grid_tables(), bufs))

    mapper.optimise(mfs, poses, 4, color_start=0.0)  # the fine grid joins at half, colour at once
    assert not torch.equal(fine.detach(), before[1]) and not torch.equal(color.detach(), before[2])
    assert all(t.grad is b for t, b in zip(model.grid_tables(), bufs))


def test_learning_rates_fall_on_a_cosine_and_start_again_at_each_call(tiny_config):
    cfg = load("fast", tiny_config)
    cfg = replace(cfg, mapping=replace(cfg.mapping, rays=64, ba_start=1.0))
    frames = list(open_source("synthetic:room?frames=3", SourceOptions(max_side=24)))
    mfs = [MapFrame.from_frame(f.without_ground_truth(), None, torch.device("cpu")) for f in frames]
    poses = {f.index: torch.tensor(f.gt_pose, dtype=torch.float32) for f in frames}
    model = SceneModel(cfg.model, SceneBound(tuple(frames[0].gt_pose[:3, 3]), 3.0, "config"))
    mapper = Mapper(model, BetaField(cfg.render), cfg)
    base = [g["lr"] for g in mapper.opt.param_groups]
    seen = []
    record = lambda it, iters, loss: seen.append([g["lr"] for g in mapper.opt.param_groups])  # noqa: E731

    mapper.optimise(mfs, poses, 4, progress=record, lr_end=0.1)
    for it, lrs in enumerate(seen):  # the rate each step used: 1 at the start, 0.1 + 0.9 cos^2 after
        f = 0.1 + 0.9 * 0.5 * (1 + math.cos(math.pi * it / 4))
        assert lrs == pytest.approx([b * f for b in base], rel=1e-12)
    assert seen[-1][0] < 0.3 * base[0]
    seen.clear()
    mapper.optimise(mfs, poses, 3, progress=record)  # the default: constant, the paper's
    assert all(lrs == base for lrs in seen)
