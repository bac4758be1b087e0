"""The SLAM's initial sphere: centred on the first camera (`model.sphere_at_camera`)."""
from dataclasses import replace

import pytest
import torch

from nicer_stream.config import load
from nicer_stream.slam.system import SlamSystem
from sources import open_source
from sources.base import SourceOptions


@pytest.mark.parametrize("at_camera", [True, False])
def test_first_camera_is_the_sphere_centre(tiny_config, at_camera):
    cfg = load("fast", tiny_config)
    cfg = replace(cfg, model=replace(cfg.model, sphere_at_camera=at_camera))
    slam = SlamSystem(cfg)
    for f in open_source("synthetic:room?frames=1", SourceOptions(max_side=32)):
        slam.step(f.without_ground_truth())
    geo, bound = slam.model.geometry, slam.model.bound
    if at_camera:
        assert torch.allclose(geo.sphere_centre, bound.normalise(torch.zeros(1, 3))[0])
        assert float(geo.sphere_radius) == pytest.approx(cfg.loss.first_depth_median_m / bound.half_extent)
    else:
        assert torch.equal(geo.sphere_centre, torch.zeros(3))
        assert float(geo.sphere_radius) == pytest.approx(cfg.model.sphere_radius)
