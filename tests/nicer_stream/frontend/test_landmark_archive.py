"""Landmarks that left the frontend's window are recognised when the camera looks back."""
from dataclasses import replace

import numpy as np
import pytest

from nicer_stream.config import FrontendConfig
from nicer_stream.frontend.frontend import ClassicalFrontend
from nicer_stream.frontend.landmark_archive import Anchor, ArchivedLandmark, LandmarkArchive
from nicer_stream.geometry.camera import project_world
from nicer_stream.types import Intrinsics
from sources import open_source
from sources.base import SourceOptions

INTR = Intrinsics(100.0, 100.0, 50.0, 40.0, 100, 80)


def _item(point, desc, T=None, frame=0):
    return ArchivedLandmark(np.asarray(point, float), np.asarray(desc, np.float32), 3.0,
                            None if T is None else Anchor(T, np.zeros(2)), frame)


def test_the_archive_forgets_its_oldest_beyond_capacity_and_age_and_rescales_points_and_anchors():
    a = LandmarkArchive(capacity=3)
    T = np.eye(4)
    T[:3, 3] = [1.0, 0.0, 0.0]
    for t in range(4):
        a.add(t, _item([0.0, 0.0, 1.0 + t], np.full(128, t), T, frame=10 * t))
    assert list(a.items) == [1, 2, 3]
    a.forget_before(20)
    assert list(a.items) == [2, 3]
    a.rescale(np.array([0.0, 0.0, 1.0]), 2.0)
    assert np.allclose(a.items[2].point, [0, 0, 5]) and np.allclose(a.items[2].anchor.T_world_cam[:3, 3], [2, 0, -1])


def test_a_keypoint_matches_the_landmark_near_its_projection_with_a_distinct_descriptor():
    """Two landmarks with one descriptor: only the one projecting near the keypoint may match;
    a keypoint whose descriptor is ambiguous among the landmarks near it fails the ratio test."""
    rng = np.random.default_rng(0)
    d = rng.random((3, 128)).astype(np.float32) * 100
    a = LandmarkArchive(10)
    a.add(7, _item([0.0, 0.0, 2.0], d[0]))   # projects to (50, 40)
    a.add(8, _item([0.6, 0.0, 2.0], d[0]))   # (80, 40): same descriptor, 30 px away
    a.add(9, _item([0.0, 0.4, 2.0], d[1]))   # (50, 60)
    uv = np.array([[52.0, 41.0], [50.0, 58.0]])
    rows, tracks = a.match(np.eye(4), INTR, uv, np.stack([d[0] + 1, d[1] + 1]), radius_px=25, ratio=0.8)
    assert dict(zip(rows.tolist(), tracks.tolist())) == {0: 7, 1: 9}
    # Every landmark within a wide radius: the first keypoint's twin (8) makes it ambiguous.
    rows, tracks = a.match(np.eye(4), INTR, uv[:1], d[:1] + 1, radius_px=100, ratio=0.8)
    assert len(rows) == 0
    uv_all, _ = project_world(np.eye(4), np.stack([x.point for x in a.items.values()]), INTR)
    assert np.allclose(uv_all, [[50, 40], [80, 40], [50, 60]])


@pytest.mark.parametrize("recognise", [True, False])
def test_a_view_seen_again_after_its_landmarks_left_the_window_is_placed_by_them(recognise):
    """Frames 0-9 of the room posed from ground truth, then six frames of noise (every track
    lost, the window of 4 emptied: the landmarks leave it), then frame 9's image again: with the
    archive its tracks are recognised as the old landmarks and PnP places it at frame 9's pose;
    without, it has no landmark and no pose."""
    src = list(open_source("synthetic:room?frames=120", SourceOptions(max_frames=10)))
    cfg = replace(FrontendConfig(corners=400), window=4, reidentify_px=20.0 if recognise else 0.0)
    fe = ClassicalFrontend(cfg)
    for f in src:
        fe.observe(f.index, f.rgb, f.intrinsics)
        fe.set_pose(f.index, f.gt_pose)
    rng = np.random.default_rng(1)
    for k in range(10, 16):
        fe.observe(k, rng.random(src[0].rgb.shape).astype(np.float32), src[0].intrinsics)
    assert not fe.landmarks
    assert (len(fe.archive) > 200) == recognise
    fe.observe(16, src[9].rgb, src[9].intrinsics)
    guess = src[9].gt_pose.copy()
    guess[:3, 3] += [0.01, -0.005, 0.005]  # a motion model's few millimetres off
    est = fe.estimate(16, guess)
    if not recognise:
        assert est is None
        return
    assert est is not None and fe.recognised >= 30
    assert np.linalg.norm(est.T_world_cam[:3, 3] - src[9].gt_pose[:3, 3]) < 0.005
    back = set(fe.obs[16][0].tolist()) & set(fe.landmarks)
    assert len(back) == fe.recognised
    # Each came back with its latest observation by a trusted frame (a held camera in the BA).
    assert all(t in fe.anchors for t in back)
