"""The frontend as an odometry on its own: it starts from two views, follows the synthetic room,
and after frames it cannot place (blank images) it says so and starts again from two views
instead of returning its last pose."""
import numpy as np

from nicer_stream.config import FrontendConfig
from nicer_stream.eval.trajectory import ate
from nicer_stream.frontend.odometry import FrontendOdometry
from sources import open_source
from sources.base import SourceOptions


def test_odometry_restarts_after_a_blackout():
    frames = list(open_source("synthetic:room?frames=120", SourceOptions(max_frames=60, max_side=320)))
    odo = FrontendOdometry(FrontendConfig(), restart_after=4)
    blank = range(30, 36)
    for f in frames:
        odo.step(f.index, np.zeros_like(f.rgb) if f.index in blank else f.rgb, f.intrinsics)
    assert any("a new two-view start" in r for r in odo.reports), odo.reports
    assert any("no PnP pose" in r for r in odo.reports)
    after = [f for f in frames[45:] if f.index in odo.poses]
    assert len(after) >= 10, "nothing placed after the restart"
    est = np.stack([odo.poses[f.index] for f in after])
    gt = np.stack([f.gt_pose for f in after])
    path = np.linalg.norm(np.diff(gt[:, :3, 3], axis=0), axis=1).sum()
    assert ate(est, gt).rmse_m < 0.05 * path, (ate(est, gt).rmse_m, path)
    # the poses after the restart move: not the last pose returned again
    assert np.ptp(est[:, :3, 3], axis=0).max() > 0


def _turned_away(frames, n):
    """`n` frames of an unrelated texture (a camera turned away) before `frames`: the first view
    shares no track with anything after them."""
    noise = np.random.default_rng(0).random(frames[0].rgb.shape[:2])[..., None].repeat(3, 2)
    return [(i, noise) for i in range(n)] + [(n + f.index, f.rgb) for f in frames]


def test_the_start_slides_past_views_that_share_no_tracks():
    frames = list(open_source("synthetic:room?frames=120", SourceOptions(max_frames=40, max_side=320)))
    odo = FrontendOdometry(FrontendConfig())
    for i, image in _turned_away(frames, 3):
        odo.step(i, image, frames[0].intrinsics)
    # Held on the first view, no start would come within the 60 frames it may wait.
    assert not any(i < 3 for i in odo.poses), sorted(odo.poses)
    assert len(odo.poses) >= 30, f"the start did not move on: {len(odo.poses)} frames placed"
