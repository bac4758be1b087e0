"""The scene bound chosen from a first frame's depth, without ground truth."""
import numpy as np

from nicer_stream.config import BoundConfig
from nicer_stream.model.bound import bound_from_points
from nicer_stream.model.bound_estimate import bound_around, bound_from_depth
from nicer_stream.types import Intrinsics

INTR = Intrinsics(fx=100.0, fy=100.0, cx=31.5, cy=23.5, width=64, height=48)


def _ramp_depth() -> np.ndarray:
    """(48, 64) z-depth: a floor-to-wall ramp from 1 m (bottom rows) to 4 m (top rows)."""
    return np.repeat(np.linspace(4.0, 1.0, 48, dtype=np.float32)[:, None], 64, 1)


def test_the_bound_reaches_behind_the_first_camera_wherever_it_is():
    T = np.eye(4)
    T[:3, 3] = [2.0, -1.0, 0.5]
    slid = bound_from_depth(_ramp_depth(), INTR, T, BoundConfig())
    centred = bound_from_depth(_ramp_depth(), INTR, T, BoundConfig(camera_margin=0.0))
    assert slid.half_extent == centred.half_extent
    # Depth runs along world z here: centred on the points, the cube starts in front of the
    # camera (which is outside it); slid, the camera has room behind it, and the frame's far
    # points are still inside.
    assert centred.world_min_max()[0][2] > 0.5
    assert slid.world_min_max()[0][2] < 0.5 - 0.1
    assert slid.world_min_max()[1][2] >= 0.5 + 3.9
    assert slid.source == centred.source == "depth_prior"


def test_bound_around_landmarks_uses_the_configured_margins(frustum_points):
    pts = frustum_points(0, 3000)
    cams = np.array([[0.0, 0.0, 0.0], [0.2, 0.0, 0.0]])  # a two-view start
    centred = bound_around(pts, cams, BoundConfig(camera_margin=0.0), "landmarks")
    assert centred == bound_from_points(pts, 1.5, "landmarks")
    slid = bound_around(pts, cams, BoundConfig(), "landmarks")
    assert np.isclose(slid.world_min_max()[0][2], -BoundConfig().camera_margin * slid.half_extent)
    wider = bound_around(pts, cams, BoundConfig(margin=2.0), "landmarks")
    assert wider.half_extent > slid.half_extent and wider.source == "landmarks"
