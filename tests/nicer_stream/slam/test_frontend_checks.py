"""The classical frontend inside SlamSystem: it seeds tracking, and a photometric pose that
disagrees with it is a detected loss (the frontend's pose is kept, the frame is not mapped)."""
from dataclasses import replace

import numpy as np
import pytest
import torch

from nicer_stream.config import load
from nicer_stream.geometry.se3 import se3_exp
from nicer_stream.slam.events import FrameTracked, KeyframeAdded
from nicer_stream.slam.motion import frontend_disagreement
from nicer_stream.slam.system import SlamSystem
from nicer_stream.config import FrontendConfig
from nicer_stream.tracking.tracker import Tracker
from sources import open_source
from sources.base import SourceOptions


def test_disagreement_bounds():
    cfg = FrontendConfig(max_disagreement_m=0.05, max_disagreement_frac=0.3, max_disagreement_deg=2.0)
    prev = torch.eye(4)
    front = se3_exp(torch.tensor([0.0, 0.0, 0.4, 0.0, 0.0, 0.0]))  # moved 40 cm: bound 12 cm
    assert frontend_disagreement(front @ se3_exp(torch.tensor([0.1, 0, 0, 0, 0, 0])), front, prev, cfg) is None
    reason = frontend_disagreement(front @ se3_exp(torch.tensor([0.15, 0, 0, 0, 0, 0])), front, prev, cfg)
    assert reason is not None and "15.0 cm from the frontend's" in reason
    reason = frontend_disagreement(front @ se3_exp(torch.tensor([0, 0, 0, 0.05, 0, 0])), front, prev, cfg)
    assert reason is not None and "rotated 2.86 deg" in reason


@pytest.fixture
def cfg(tiny_config):
    c = load("fast", tiny_config)
    return replace(c, max_side=160, tracking=replace(c.tracking, frontend="classical"),
                   mapping=replace(c.mapping, init="first_frame"))


def _frames(n):
    return [f.without_ground_truth() for f in open_source("synthetic:room?frames=60", SourceOptions(max_frames=n, max_side=160))]


def test_a_wrong_photometric_pose_is_detected_and_the_frontend_pose_kept(cfg, monkeypatch):
    """Tracking against a perturbed map: the tracker's result is moved 30 cm off whatever
    it started from (the frontend's pose): the check fires, says why, keeps the frontend's pose."""
    slam = SlamSystem(cfg)
    frames = _frames(9)
    for f in frames[:8]:
        slam.step(f)
    assert slam.frontend.landmarks, "the frontend triangulated nothing"
    seeds = []
    real = Tracker.track

    def wrong(self, frame, T_init):
        seeds.append(T_init.clone())
        res = real(self, frame, T_init)
        return replace(res, T_world_cam=T_init @ se3_exp(torch.tensor([0.3, 0.0, 0.0, 0.0, 0.0, 0.0])))

    monkeypatch.setattr(Tracker, "track", wrong)
    events = slam.step(frames[8])
    tracked = [e for e in events if isinstance(e, FrameTracked)][0]
    assert tracked.lost is not None and "from the frontend's" in tracked.lost, tracked.lost
    assert np.allclose(tracked.T_world_cam, seeds[0].double().numpy(), atol=1e-6)  # the frontend's pose
    assert 8 in slam.lost_frames and 8 not in slam.keyframes
    assert not any(isinstance(e, KeyframeAdded) for e in events)


def test_agreeing_poses_pass_and_the_frontend_seeds_tracking(cfg):
    slam = SlamSystem(cfg)
    for f in _frames(8):
        slam.step(f)
    assert slam.lost_frames == []
    assert slam.frontend_seconds > 0
    est = slam.frontend.estimate(7, slam.poses[7].double().numpy())
    assert est is not None and est.inliers >= cfg.frontend.min_inliers
