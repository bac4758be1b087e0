"""Filling stereo holes with the plane of their rim: exact on a plane, refused where the rim
is not one plane, small holes and thin strips left alone."""
import numpy as np
import torch

from nicer_stream.geometry.camera import camera_dirs, pixel_grid
from nicer_stream.priors.plane_fill import fill_planar_holes, fit_plane
from nicer_stream.types import Intrinsics

INTR = Intrinsics(fx=100.0, fy=100.0, cx=59.5, cy=39.5, width=120, height=80)


def camera_rays(intr):
    """(H, W, 3) rays with z = 1 of every pixel centre."""
    return camera_dirs(pixel_grid(intr, dtype=torch.float64), intr).numpy().reshape(intr.height, intr.width, 3)


def _plane_depth(n, c):
    """z-depth (H, W) of the camera-frame plane n.x = c."""
    return (c / (camera_rays(INTR) @ np.asarray(n, float))).astype(np.float32)


def test_fit_plane_recovers_a_plane_among_outliers():
    rng = np.random.default_rng(0)
    n = np.array([0.3, -0.2, 0.9])
    n /= np.linalg.norm(n)
    rays = camera_rays(INTR).reshape(-1, 3)[rng.choice(INTR.width * INTR.height, 400, replace=False)]
    points = rays * (2.0 / (rays @ n))[:, None]
    points[:100] *= 0.7  # a quarter off the plane
    m, c, share = fit_plane(points, 0.01, rng)
    assert abs(share - 0.75) < 0.01
    np.testing.assert_allclose(m * np.sign(m @ n), n, atol=1e-6)
    assert abs(c * np.sign(m @ n) - 2.0) < 1e-6


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
