"""The SLAM's start without a depth prior moves its first view on when that view shares no tracks
with the latest frame (a camera that turned away), instead of waiting on it: the passed frames
get no pose and are reported."""
from dataclasses import replace

import numpy as np
import torch

from nicer_stream.config import load
from nicer_stream.slam.events import FrameTracked
from nicer_stream.slam.system import SlamSystem
from sources import open_source
from sources.base import SourceOptions


def test_start_moves_past_frames_that_share_no_tracks(tiny_config):
    torch.manual_seed(0)
    c = load("fast", tiny_config)
    cfg = replace(c, max_side=160, tracking=replace(c.tracking, frontend="classical"),
                  mapping=replace(c.mapping, init="two_view", init_max_frames=60))
    frames = [f.without_ground_truth() for f in open_source("synthetic:room?frames=60",
                                                              SourceOptions(max_frames=16, max_side=160))]
    noise = np.random.default_rng(0).random(frames[0].rgb.shape[:2])[..., None].repeat(3, 2).astype(np.float32)
    turned = [replace(frames[0], index=i, rgb=noise, detail=None) for i in range(3)]
    shifted = [replace(f, index=f.index + 3) for f in frames]
    slam = SlamSystem(cfg)
    tracked = set()
    for f in turned + shifted:
        tracked |= {e.index for e in slam.step(f) if isinstance(e, FrameTracked)}
    tracked |= {e.index for e in slam.finish() if isinstance(e, FrameTracked)}
    assert slam.model is not None, "no start"
    assert set(slam.unposed) >= {0, 1}, slam.unposed
    assert not tracked & set(slam.unposed)
    assert slam.keyframes[0] >= 2
    assert slam.health_summary()["unposed_before_start"] == slam.unposed
