"""Filling stereo holes with the plane of their rim: exact on a plane, refused where the rim
is not one plane, small holes and thin strips left alone."""
import numpy as np
import torch

from nicer_stream.geometry.camera import camera_dirs, pixel_grid
from nicer_stream.priors.plane_fill import fill_planar_holes, fit_wall_planes
from nicer_stream.types import Intrinsics

INTR = Intrinsics(fx=100.0, fy=100.0, cx=59.5, cy=39.5, width=120, height=80)


def camera_rays(intr):
    """(H, W, 3) rays with z = 1 of every pixel centre."""
    return camera_dirs(pixel_grid(intr, dtype=torch.float64), intr).numpy().reshape(intr.height, intr.width, 3)


def _plane_depth(n, c):
    """z-depth (H, W) of the camera-frame plane n.x = c."""
    return (c / (camera_rays(INTR) @ np.asarray(n, float))).astype(np.float32)


def test_wall_planes_recover_a_plane_among_points_in_front_of_it():
    rng = np.random.default_rng(0)
    n = np.array([0.3, -0.2, 0.9])
    n /= np.linalg.norm(n)
    rays = camera_rays(INTR).reshape(-1, 3)[rng.choice(INTR.width * INTR.height, 400, replace=False)]
    points = rays * (2.0 / (rays @ n))[:, None]
    points[:100] *= 0.7  # a quarter in front of the plane (foreground)
    planes, share = fit_wall_planes(points, 0.01, rng, max_planes=1)
    assert len(planes) == 1 and abs(share - 0.75) < 0.01
    m, c = planes[0]
    np.testing.assert_allclose(m, n, atol=1e-6)  # oriented: the camera on the side n.x < c
    assert abs(c - 2.0) < 1e-6


def test_a_plane_with_points_behind_it_is_not_a_wall():
    rng = np.random.default_rng(0)
    rays = camera_rays(INTR).reshape(-1, 3)[rng.choice(INTR.width * INTR.height, 400, replace=False)]
    points = rays * 2.0
    points[:150] *= 1.5  # 37% behind the z = 2 plane: that plane is a foreground surface
    planes, share = fit_wall_planes(points, 0.01, rng, max_planes=2, min_share=0.2, max_behind=0.1)
    np.testing.assert_allclose(planes[0][0], [0, 0, 1], atol=1e-6)
    assert abs(planes[0][1] - 3.0) < 1e-6 and len(planes) == 1 and abs(share - 0.375) < 0.01


def test_a_hole_in_a_plane_is_filled_with_the_plane():
    truth = _plane_depth([0.2, 0.1, 1.0], 2.5)
    depth = truth.copy()
    depth[20:50, 30:80] = 0  # an untextured patch of the wall
    out = fill_planar_holes(depth, INTR)
    np.testing.assert_allclose(out, truth, rtol=1e-5)


def test_a_hole_whose_rim_is_two_surfaces_stays_unknown():
    depth = np.where(np.arange(120)[None, :] < 55, 1.0, 3.0).repeat(80, 0).astype(np.float32)
    depth[20:50, 30:80] = 0  # its rim: half a near surface, half a far one
    out = fill_planar_holes(depth, INTR)
    np.testing.assert_array_equal(out, depth)


def test_small_holes_and_thin_strips_stay_unknown():
    depth = _plane_depth([0.0, 0.0, 1.0], 2.0)
    depth[10:14, 10:14] = 0  # 16 px: below min_area
    depth[:, 60:62] = 0  # a 2-px strip (a dropped depth edge) across the image
    out = fill_planar_holes(depth, INTR, min_area=0.01)
    np.testing.assert_array_equal(out, depth)


def test_only_mostly_untextured_holes_are_filled_when_told_which_pixels_are_blank():
    truth = _plane_depth([0.2, 0.1, 1.0], 2.5)
    depth = truth.copy()
    depth[20:50, 30:80] = 0
    blank = np.zeros(depth.shape, bool)
    np.testing.assert_array_equal(fill_planar_holes(depth, INTR, blank), depth)  # textured: an occlusion, say
    blank[20:50, 30:60] = True  # 60% of the hole untextured
    np.testing.assert_allclose(fill_planar_holes(depth, INTR, blank), truth, rtol=1e-5)


def test_a_hole_across_a_room_corner_takes_the_nearer_wall_at_each_pixel():
    """Two walls meeting in a concave corner (seen from inside): each pixel's depth is the
    nearer of the two planes, and a hole spanning the corner is filled with both."""
    left, right = _plane_depth([-0.6, 0.0, 0.8], 2.0), _plane_depth([0.6, 0.0, 0.8], 2.0)
    truth = np.minimum(left, right)
    depth = truth.copy()
    depth[15:65, 25:95] = 0
    np.testing.assert_allclose(fill_planar_holes(depth, INTR, max_planes=3), truth, rtol=1e-5)
    single = fill_planar_holes(depth, INTR, max_planes=1)  # one plane explains half the rim
    np.testing.assert_array_equal(single, depth)


def test_a_foreground_plane_holding_most_of_the_rim_does_not_fill_the_hole():
    """Three quarters of the rim on a near surface, the rest on the wall behind it: the near
    plane has the wall's rim points behind it, so it is not the hole's wall."""
    depth = np.full((80, 120), 3.0, np.float32)
    depth[:, :75] = 1.0  # a near board over most of the hole's rim
    depth[20:50, 30:80] = 0
    np.testing.assert_array_equal(fill_planar_holes(depth, INTR), depth)
    old = fill_planar_holes(depth, INTR, max_behind=1.0)  # without the test the board's plane fills it
    assert (old[20:50, 30:80] == 1.0).all()
