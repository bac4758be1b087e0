"""A small map of the synthetic room fitted with GT poses, shared by the tracking tests."""
from dataclasses import replace

import numpy as np
import pytest
import torch

from nicer_stream.config import load
from nicer_stream.geometry.se3 import invert, rotation_angle
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mapping.mapper import Mapper
from nicer_stream.model.bound import SceneBound
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from sources import open_source
from sources.base import SourceOptions


@pytest.fixture(scope="session")  # read-only for its users: built once (~1 min), not per module
def fitted(tmp_path_factory, tiny_toml):
    """A small map of the synthetic room fitted with GT poses: (cfg, frames, map frames, poses, model, beta)."""
    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("cfg") / "tiny.toml"
    path.write_text(tiny_toml)
    cfg = load("fast", path)
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
    return cfg, frames, mfs, poses, model, beta


@pytest.fixture
def pose_error():
    """(translation m, rotation rad) of T relative to T_gt."""
    return _pose_error


def _pose_error(T_gt, T):
    d = invert(T_gt) @ T
    return float(d[:3, 3].norm()), float(rotation_angle(d[:3, :3]))
