"""Plane-sweep stereo on the synthetic room with known poses: depth within a few percent on
textured surfaces, untextured and unseen pixels not confident, the homography by hand."""
import numpy as np
import pytest

from nicer_stream.config import StereoConfig
from nicer_stream.priors.stereo import (TUNED_SIDE, best_planes_reference, best_planes_streaming, drop_depth_edges,
                                        drop_speckles, local_std, plane_homography, scaled_to, sweep_depth)
from nicer_stream.types import Intrinsics
from sources import open_source
from sources.base import SourceOptions


@pytest.fixture(scope="module")
def room():
    return list(open_source("synthetic:room?frames=40", SourceOptions(max_frames=16)))


def _range(f):
    return 0.3, 2.5 * float(np.median(f.gt_depth[f.gt_depth > 0]))


def test_plane_homography_maps_a_point_on_the_plane_like_projection():
    K = Intrinsics(fx=200.0, fy=210.0, cx=80.0, cy=60.0, width=160, height=120).matrix()
    rng = np.random.default_rng(0)
    a = rng.normal(size=3) * 0.1
    c, s = np.cos(a[2]), np.sin(a[2])
    T = np.eye(4)
    T[:3, :3] = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    T[:3, 3] = [0.2, -0.1, 0.05]
    X = np.array([0.3, -0.2, 2.5])  # on the plane z = 2.5 of the reference camera
    u_ref = K @ X
    u_part = K @ (T[:3, :3] @ X + T[:3, 3])
    h = plane_homography(K, T, 2.5) @ u_ref
    np.testing.assert_allclose(h[:2] / h[2], u_part[:2] / u_part[2], atol=1e-9)


def test_sweep_depth_on_textured_surfaces_within_3_percent(room):
    f = room[10]
    d = sweep_depth(f.rgb, f.gt_pose, [(room[5].rgb, room[5].gt_pose), (room[15].rgb, room[15].gt_pose)],
                       f.intrinsics, *_range(f))
    m = (d > 0) & (f.gt_depth > 0)
    rel = np.abs(d[m] - f.gt_depth[m]) / f.gt_depth[m]
    assert m.mean() > 0.5, m.mean()  # most of the room is textured
    assert np.median(rel) < 0.03, np.median(rel)  # measured 0.64%
    assert np.mean(rel > 0.1) < 0.1


@pytest.mark.parametrize("n_partners", [1, 2, 3])
def test_the_streamed_best_planes_equal_those_of_the_whole_cost_volume(n_partners):
    rng = np.random.default_rng(n_partners)
    # Costs on a coarse grid (many ties: the first minimum must win in both) with unseen (2.0) runs.
    costs = np.round(rng.uniform(0, 1, (n_partners, 12, 9, 11)) * 8).astype(np.float32) / 8
    costs[:, :, :3, :4] = 2.0  # outside every partner
    costs[0, 4:, 5:] = 2.0  # the first partner loses the far planes of a corner
    ref = best_planes_reference(costs, 2)
    got = best_planes_streaming((list(costs[:, i]) for i in range(costs.shape[1])), 2)
    for name in ("k", "c0", "agree"):
        np.testing.assert_array_equal(getattr(got, name), getattr(ref, name), err_msg=name)
    inner = (ref.k > 0) & (ref.k < costs.shape[1] - 1)  # the parabola's neighbours exist only there
    np.testing.assert_array_equal(got.cm[inner], ref.cm[inner])
    np.testing.assert_array_equal(got.cp[inner], ref.cp[inner])


def test_a_streamed_sweep_gives_the_depth_of_the_whole_volume(room):
    f = room[10]
    partners = [(room[5].rgb, room[5].gt_pose), (room[15].rgb, room[15].gt_pose)]
    streamed = sweep_depth(f.rgb, f.gt_pose, partners, f.intrinsics, *_range(f))
    np.testing.assert_array_equal(streamed, sweep_depth(f.rgb, f.gt_pose, partners, f.intrinsics, *_range(f), volume=True))
    assert (streamed > 0).mean() > 0.5


def test_untextured_and_unseen_pixels_are_not_confident(room):
    f, p = room[10], room[14]
    ref = f.rgb.copy()
    ref[60:140, 100:220] = 0.5  # a blank patch: any depth matches it
    d = sweep_depth(ref, f.gt_pose, [(p.rgb, p.gt_pose)], f.intrinsics, *_range(f))
    assert (d[70:130, 110:210] > 0).mean() < 0.05
    # Pixels whose GT point leaves the partner's image have nothing to match.
    from nicer_stream.priors.oracle import flow_from_depth_pose

    _, seen = flow_from_depth_pose(f.gt_depth, f.gt_pose, f.intrinsics, p.gt_pose, p.intrinsics)
    unseen = ~seen & (f.gt_depth > 0)
    assert unseen.sum() > 500
    assert (d[unseen] > 0).mean() < 0.2


def test_sweep_needs_a_partner(room):
    f = room[0]
    with pytest.raises(ValueError):
        sweep_depth(f.rgb, f.gt_pose, [], f.intrinsics, 0.3, 5.0)


def test_the_edge_filter_drops_both_sides_of_a_depth_step_and_keeps_a_slanted_plane():
    rows, cols = np.indices((40, 60))
    slanted = (2.0 + 0.005 * cols).astype(np.float32)  # 0.25% per pixel: a floor seen at an angle
    step = np.where(cols < 30, 1.0, 2.0).astype(np.float32)
    np.testing.assert_array_equal(drop_depth_edges(slanted, 7, 0.1), slanted)
    out = drop_depth_edges(step, 7, 0.1)
    assert (out[:, 27:33] == 0).all()  # within 3 px of the step: its window straddles it
    np.testing.assert_array_equal(out[:, :27], step[:, :27])
    np.testing.assert_array_equal(out[:, 33:], step[:, 33:])
    holes = slanted.copy()
    holes[10:20, 10:20] = 0  # unknown pixels neither count as an edge nor come back
    np.testing.assert_array_equal(drop_depth_edges(holes, 7, 0.1), holes)
    np.testing.assert_array_equal(drop_depth_edges(step, 1, 0.1), step)  # off


def test_the_speckle_filter_drops_small_islands_and_keeps_large_surfaces():
    d = np.full((60, 80), 2.0, np.float32)
    d[10:14, 10:14] = 1.0  # a 16-pixel island of wrong depth inside the wall
    d[40:44, 60:64] = 0.0
    d[41:43, 61:63] = 3.0  # a 4-pixel island inside a hole
    out = drop_speckles(d, 50, 0.02)
    assert (out[10:14, 10:14] == 0).all() and (out[41:43, 61:63] == 0).all()
    keep = np.ones_like(d, bool)
    keep[10:14, 10:14] = keep[40:44, 60:64] = False
    np.testing.assert_array_equal(out[keep], d[keep])
    np.testing.assert_array_equal(drop_speckles(d, 0, 0.02), d)  # off
    # A 200-pixel ramp of ~1.3% per pixel is one blob at a 2% step, so it stays; cut at 4% steps it falls apart.
    ramp = np.tile(np.linspace(1.0, 1.5, 40, dtype=np.float32), (5, 1))
    np.testing.assert_array_equal(drop_speckles(ramp, 150, 0.02), ramp)
    assert (drop_speckles(ramp[:, ::3], 20, 0.02) == 0).all()


def test_local_std_is_zero_on_flat_grey_and_the_std_of_a_checkerboard():
    flat = np.full((20, 20), 0.3, np.float32)
    assert np.abs(local_std(flat, 5)).max() < 1e-4
    board = (np.indices((20, 20)).sum(0) % 2).astype(np.float32)  # 0 / 1 alternating
    assert abs(float(local_std(board, 4)[10, 10]) - 0.5) < 1e-4  # an even window: half of each


def test_a_sweep_larger_than_the_tuned_size_scales_its_windows_and_a_smaller_one_keeps_them():
    p = StereoConfig(window=9, edge_window=5, speckle_size=400)
    assert scaled_to(p, TUNED_SIDE) == p and scaled_to(p, 320) == p
    big = scaled_to(p, 960)
    assert (big.window, big.edge_window, big.speckle_size) == (13, 7, 900)  # 1.5x the sides, 2.25x the area
    big = scaled_to(p, 1200)
    assert (big.window, big.edge_window, big.speckle_size) == (17, 9, 1406)
    assert scaled_to(StereoConfig(edge_window=0), 1200).edge_window == 0  # off stays off
    assert big.min_ncc == p.min_ncc and big.max_side == p.max_side
