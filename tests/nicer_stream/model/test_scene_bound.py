"""SceneBound normalisation and the scene model's world-unit queries."""
import numpy as np
import torch

from nicer_stream.config import MappingConfig, ModelConfig
from nicer_stream.model.bound import SceneBound, bound_from_points
from nicer_stream.model.scene import SceneModel

SMALL = ModelConfig(coarse_res=8, fine_levels=2, fine_res_min=8, fine_res_max=12, color_levels=2,
                    color_res_max=16, color_log2_table=10)


def test_normalise_round_trip_and_cube_corners():
    b = SceneBound((1.0, -2.0, 0.5), 3.0, "config")
    x = torch.randn(10, 3, dtype=torch.float64)
    assert torch.allclose(b.denormalise(b.normalise(x)), x, atol=1e-12)
    lo, hi = b.world_min_max()
    assert np.allclose(lo, [-2, -5, -2.5]) and np.allclose(hi, [4, 1, 3.5])
    corners = torch.from_numpy(np.stack([lo, hi]))
    assert torch.allclose(b.normalise(corners), torch.tensor([[-1.0] * 3, [1.0] * 3], dtype=torch.float64))
    assert b.to_dict() == {"centre": [1.0, -2.0, 0.5], "half_extent": 3.0, "source": "config"}


def test_bound_from_points_covers_points_with_margin():
    rng = np.random.default_rng(0)
    pts = rng.uniform([0, 0, 1], [2, 1, 5], size=(5000, 3))
    b = bound_from_points(pts, 1.5, "depth_prior")
    assert np.allclose(b.centre, [1, 0.5, 3], atol=0.05)
    assert abs(b.half_extent - 2 * 1.5) < 0.1  # longest side 4 m -> half 2 m, times margin
    assert b.source == "depth_prior"
    tiny = bound_from_points(np.zeros((10, 3)), 1.5, "depth_prior")
    assert tiny.half_extent == 0.5  # floor against degenerate priors


def test_scene_sdf_world_is_metres_and_groups_cover_all_parameters():
    torch.manual_seed(0)
    b = SceneBound((0.5, 0.0, -1.0), 2.0, "config")
    model = SceneModel(SMALL, b)
    # A world point at distance 1 m from the centre: SDF ~ (0.9 - 0.5) * 2 m.
    x = torch.tensor([[0.5, 0.0, 0.0]])
    assert abs(model.sdf_world(x).item() - (SMALL.sphere_radius - 0.5) * 2.0) < 2e-2
    rgb = model.color_world(x, torch.tensor([[0.0, 0.0, -1.0]]))
    assert rgb.shape == (1, 3) and (rgb >= 0).all() and (rgb <= 1).all()
    groups = model.param_groups(MappingConfig())
    ids = [id(p) for g in groups.values() for p in g["params"]]
    assert len(ids) == len(set(ids)) == len(list(model.parameters()))
    assert groups["coarse"]["lr"] == MappingConfig().lr * MappingConfig().lr_geo_grid_factor


def test_bound_slides_until_the_camera_has_its_margin(frustum_points):
    pts = frustum_points(1)
    centred = bound_from_points(pts, 1.5, "depth_prior")
    slid = bound_from_points(pts, 1.5, "depth_prior", cameras=np.zeros((1, 3)), camera_margin=0.25, edge=0.05)
    half = slid.half_extent
    assert half == centred.half_extent  # the same resolution per metre
    # Centred on the points, the camera is nearer the cube's back face than a quarter of the half
    # side; slid, exactly that far (the least shift), and x, y (already inside) do not move.
    assert centred.world_min_max()[0][2] > -0.25 * half
    assert np.isclose(slid.world_min_max()[0][2], -0.25 * half)
    assert np.allclose(slid.centre[:2], centred.centre[:2])
    # Without a camera margin the cube stays centred.
    same = bound_from_points(pts, 1.5, "depth_prior", cameras=np.zeros((1, 3)), camera_margin=0.0)
    assert same == centred


def test_bound_slides_no_further_than_keeps_the_points_inside(frustum_points):
    pts = frustum_points(2)
    plo, phi = np.percentile(pts, 1, axis=0), np.percentile(pts, 99, axis=0)
    e = 0.05 * (phi - plo).max()
    # A camera far behind: the cube stops where the grown box would leave it.
    far = bound_from_points(pts, 1.5, "depth_prior", cameras=np.array([[0.0, 0.0, -50.0]]), camera_margin=0.25,
                            edge=0.05)
    lo, hi = far.world_min_max()
    assert np.isclose(hi[2], phi[2] + e) and (lo <= plo - e + 1e-9).all() and (hi >= phi + e - 1e-9).all()
    # margin 1: the cube is the box's longest side; there is no room to slide along it.
    centred = bound_from_points(pts, 1.0, "depth_prior")
    slid = bound_from_points(pts, 1.0, "depth_prior", cameras=np.zeros((1, 3)), camera_margin=0.25, edge=0.05)
    longest = int(np.argmax(phi - plo))
    assert np.isclose(slid.centre[longest], centred.centre[longest])
