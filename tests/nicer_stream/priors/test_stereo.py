"""Plane-sweep stereo on the synthetic room with known poses: depth within a few percent on
textured surfaces, untextured and unseen pixels not confident, the homography by hand."""
import numpy as np
import pytest

from nicer_stream.priors.stereo import plane_homography, sweep_depth
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
