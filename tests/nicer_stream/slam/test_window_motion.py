"""Frame selection (Sec. 3.4), motion model and tracking-failure checks."""
import math
import random

import pytest
import torch

from nicer_stream.config import MappingConfig, TrackingConfig
from nicer_stream.geometry.se3 import se3_exp
from nicer_stream.slam.motion import predict_pose, tracking_failure
from nicer_stream.slam.window import ba_frames, select_window


def test_window_size_and_membership():
    cfg = MappingConfig()
    kfs = list(range(0, 400, 10))
    w = select_window(kfs, 405, cfg, random.Random(0))
    assert 405 in w
    assert len(w) == 16  # 5 random + 10 recent + current (paper K=16)
    recent = set(kfs[-cfg.recent_pool:])
    assert len(set(w) & recent) >= cfg.window_recent
    assert set(w) - {405} <= set(kfs)


def test_window_small_pool_has_no_duplicates():
    w = select_window([0, 10], 12, MappingConfig(), random.Random(1))
    assert w == [0, 10, 12]


def test_ba_frames_near_half_without_anchor():
    w = [0, 10, 20, 30, 40, 45]
    ba = ba_frames(w, 45, anchor=0)
    assert ba == {45, 40, 30}
    assert 0 not in ba_frames([0, 5], 5, anchor=0)


def test_constant_velocity_prediction_extrapolates():
    step = se3_exp(torch.tensor([0.1, 0.0, 0.02, 0.0, 0.05, 0.0]))
    T0 = se3_exp(torch.tensor([0.3, -0.2, 1.0, 0.1, 0.2, -0.3]))
    T1 = T0 @ step
    pred = predict_pose([T0, T1], "constant_velocity")
    assert torch.allclose(pred, T1 @ step, atol=1e-5)
    assert torch.equal(predict_pose([T0, T1], "previous"), T1)
    with pytest.raises(ValueError):
        predict_pose([T0], "magic")


def test_tracking_failure_reasons():
    cfg = TrackingConfig(max_jump_m=0.5, max_jump_deg=30, loss_jump=4.0)
    I = torch.eye(4)
    assert tracking_failure(I, I, 0.1, [0.1, 0.1, 0.1], cfg) is None
    far = se3_exp(torch.tensor([1.0, 0, 0, 0, 0, 0]))
    assert "jumped" in tracking_failure(far, I, 0.1, [], cfg)
    turned = se3_exp(torch.tensor([0, 0, 0, 0, math.radians(40), 0]))
    assert "rotated" in tracking_failure(turned, I, 0.1, [], cfg)
    assert "median" in tracking_failure(I, I, 1.0, [0.1, 0.1, 0.1], cfg)
    nan = I.clone()
    nan[0, 3] = float("nan")
    assert "non-finite" in tracking_failure(nan, I, 0.1, [], cfg)
