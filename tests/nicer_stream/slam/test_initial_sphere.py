"""The SLAM's initial sphere (`model.sphere_centre`): the first camera must start in free space."""
from dataclasses import replace

import pytest
import torch

from nicer_stream.config import load
from nicer_stream.errors import UserError
from nicer_stream.model.geometry import initial_sphere
from nicer_stream.slam.system import SlamSystem
from sources import open_source
from sources.base import SourceOptions


def test_auto_moves_the_sphere_only_for_a_camera_outside_it():
    inside, outside = torch.tensor([0.5, -0.4, 0.3]), torch.tensor([0.6, -0.7, 0.5])  # |.| 0.71, 1.05
    centre, radius = initial_sphere("auto", inside, 0.9, 0.7)
    assert torch.equal(centre, torch.zeros(3)) and radius == 0.9
    centre, radius = initial_sphere("auto", outside, 0.9, 0.7)
    assert torch.equal(centre, outside) and radius == 0.7
    centre, radius = initial_sphere("camera", inside, 0.9, 0.7)
    assert torch.equal(centre, inside) and radius == 0.7
    centre, radius = initial_sphere("bound", outside, 0.9, 0.7)
    assert torch.equal(centre, torch.zeros(3)) and radius == 0.9


@pytest.mark.parametrize("mode", ["camera", "bound"])
def test_the_slam_places_the_sphere(tiny_config, mode):
    cfg = load("fast", tiny_config)
    cfg = replace(cfg, model=replace(cfg.model, sphere_centre=mode))
    slam = SlamSystem(cfg)
    for f in open_source("synthetic:room?frames=1", SourceOptions(max_side=32)):
        slam.step(f.without_ground_truth())
    geo, bound = slam.model.geometry, slam.model.bound
    if mode == "camera":
        assert torch.allclose(geo.sphere_centre, bound.normalise(torch.zeros(1, 3))[0])
        assert float(geo.sphere_radius) == pytest.approx(cfg.loss.first_depth_median_m / bound.half_extent)
    else:
        assert torch.equal(geo.sphere_centre, torch.zeros(3))
        assert float(geo.sphere_radius) == pytest.approx(cfg.model.sphere_radius)


def test_unknown_mode_is_a_clear_error(tiny_config):
    cfg = load("fast", tiny_config)
    with pytest.raises(UserError, match="sphere_centre"):
        SlamSystem(replace(cfg, model=replace(cfg.model, sphere_centre="middle")))
