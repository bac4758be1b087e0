"""A frontend that fails inside the SLAM: from frame 12 on it returns its previous pose (frozen)
or a tenth of its motion (a collapsing scale). The SLAM reports it within 10 frames and keeps
the map's pose (or reports the frame lost), never the faulty one silently."""
from dataclasses import replace

import cv2
import numpy as np
import pytest
import torch

from nicer_stream.config import load
from nicer_stream.frontend.frontend import FrontendPose
from nicer_stream.slam.events import FrameTracked, TrackingWarning
from nicer_stream.slam.system import SlamSystem
from sources import open_source
from sources.base import SourceOptions

FAULT_FROM = 12


@pytest.fixture
def cfg(tiny_config):
    cv2.setRNGSeed(0)
    torch.manual_seed(0)
    c = load("fast", tiny_config)
    return replace(c, max_side=160, tracking=replace(c.tracking, frontend="classical"),
                   mapping=replace(c.mapping, init="first_frame"))


def _faulty(kind):
    """A ClassicalFrontend.estimate that turns faulty at FAULT_FROM, and the poses it returned."""
    returned: dict[int, np.ndarray] = {}

    def make(real):
        def estimate(self, index, T_guess):
            est = real(self, index, T_guess)
            if est is None or index < FAULT_FROM or index - 1 not in returned:
                if est is not None:
                    returned[index] = est.T_world_cam
                return est
            prev = returned[index - 1]
            if kind == "frozen":
                T = prev.copy()
            else:  # a tenth of the motion the real estimate found since the previous frame
                T = est.T_world_cam.copy()
                T[:3, 3] = prev[:3, 3] + 0.1 * (est.T_world_cam[:3, 3] - prev[:3, 3])
            returned[index] = T
            return FrontendPose(T, est.inliers, est.visible, est.median_depth)
        return estimate
    return make, returned


@pytest.mark.parametrize("kind", ["frozen", "shrunk"])
def test_a_faulty_frontend_is_reported_and_not_trusted(cfg, monkeypatch, kind):
    slam = SlamSystem(cfg)
    make, returned = _faulty(kind)
    monkeypatch.setattr(type(slam.frontend), "estimate", make(type(slam.frontend).estimate))
    frames = [f.without_ground_truth() for f in open_source("synthetic:room?frames=60",
                                                              SourceOptions(max_frames=FAULT_FROM + 18, max_side=160))]
    tracked, warned = {}, []
    for f in frames:
        for e in slam.step(f):
            if isinstance(e, FrameTracked):
                tracked[e.index] = e
            if isinstance(e, TrackingWarning):
                warned.append(e)
    faults = [r for r in slam.health.reports if r.index >= FAULT_FROM and r.kind != "lost"]
    assert faults, f"no report of the {kind} frontend: {[str(r) for r in slam.health.reports]}"
    assert faults[0].index < FAULT_FROM + 10, str(faults[0])
    # From the report on, no frame silently keeps the faulty pose: the map's pose, or lost.
    for i in range(faults[0].index, len(frames)):
        if i in returned and i >= FAULT_FROM and i not in slam.lost_frames:
            assert i in slam.front.distrusted, f"frame {i} kept the faulty pose without a check"
    # ... and handed to the sinks as an event (Rerun's text log, MCAP's /tracking/warnings)
    assert any(w.index == faults[0].index and w.kind == f"frontend {faults[0].kind}" for w in warned), warned
    summary = slam.health_summary()
    assert sum(summary["frontend_reports"].values()) >= 1
