"""Flows on request: the SLAM fed each frame's depth alone and a way to get its flows gives the
same poses as the SLAM fed the flows up front, and asks for the flows of fewer frames (a frame
that is neither a keyframe nor mapped, and whose tracking starts from the frontend, needs none)."""
from dataclasses import replace

import numpy as np
import torch

from nicer_stream.config import load
from nicer_stream.runtime.frame_priors import make_engine
from nicer_stream.runtime.prior_stage import PriorStage
from nicer_stream.slam.events import FrameTracked, KeyframeAdded
from nicer_stream.slam.system import SlamSystem
from sources import open_source
from sources.base import SourceOptions


def _run(cfg, frames, deferred: bool):
    torch.manual_seed(0)
    engine = make_engine("none", "dis", "cpu")
    calls = []
    real = engine.flow_provider.flow_both
    engine.flow_provider.flow_both = lambda a, b: calls.append((a.index, b.index)) or real(a, b)
    stage, slam, poses = PriorStage(engine), SlamSystem(cfg), {}
    for f in frames:
        pri = stage(f, flows=not deferred)
        events = slam.step(f.without_ground_truth(), pri, stage.deferred_flows if deferred else None)
        events += slam.finish() if f is frames[-1] else []
        for e in events:
            if isinstance(e, KeyframeAdded):
                stage.add_keyframe(next(x for x in frames if x.index == e.index))
            if isinstance(e, FrameTracked):
                poses[e.index] = e.T_world_cam
    return poses, calls


def test_deferred_flows_give_the_same_poses_with_fewer_flows(tiny_config):
    c = load("fast", tiny_config)
    cfg = replace(c, max_side=160, tracking=replace(c.tracking, frontend="classical", refine="keyframes"))
    frames = list(open_source("synthetic:room?frames=60", SourceOptions(max_frames=24, max_side=160)))
    eager, eager_calls = _run(cfg, frames, deferred=False)
    lazy, lazy_calls = _run(cfg, frames, deferred=True)
    assert sorted(lazy) == sorted(eager) and len(eager) == len(frames)
    for k in eager:
        np.testing.assert_allclose(lazy[k], eager[k], atol=1e-6, err_msg=f"frame {k}")
    assert set(lazy_calls) < set(eager_calls), (len(lazy_calls), len(eager_calls))
    assert len(lazy_calls) <= 0.7 * len(eager_calls), (len(lazy_calls), len(eager_calls))
