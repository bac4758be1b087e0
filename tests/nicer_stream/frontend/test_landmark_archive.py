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
from tests.nicer_stream.frontend.archive_match_reference import match_reference
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


def test_the_radius_search_matches_the_brute_force_reference():
    """3000 landmarks, 900 keypoints: 300 of them re-observe a landmark (its descriptor with
    noise, near its projection), the rest are new. The k-d tree's pairs give what OpenCV's
    brute-force matcher gives over a mask of every pair within the radius, and find most of the
    re-observed ones."""
    rng = np.random.default_rng(3)
    intr = Intrinsics(525.0, 525.0, 320.0, 240.0, 640, 480)
    a = LandmarkArchive(10_000)
    pts = np.c_[rng.uniform(-1.5, 1.5, (3000, 2)), rng.uniform(1.5, 4.0, 3000)]
    lib = rng.random((3000, 128)).astype(np.float32) * 100
    for t in range(3000):
        a.add(100 + t, _item(pts[t], lib[t]))
    px, z = project_world(np.eye(4), pts, intr)
    seen = rng.choice(np.flatnonzero((px[:, 0] > 0) & (px[:, 0] < 640) & (px[:, 1] > 0) & (px[:, 1] < 480)), 300, replace=False)
    uv = np.concatenate([px[seen] + rng.normal(0, 3, (300, 2)), rng.uniform([0, 0], [640, 480], (600, 2))])
    desc = np.concatenate([lib[seen] + rng.normal(0, 3, (300, 128)), rng.random((600, 128)) * 100]).astype(np.float32)
    fast = a.match(np.eye(4), intr, uv, desc, 20.0, 0.8)
    slow = match_reference(a, np.eye(4), intr, uv, desc, 20.0, 0.8)
    assert sorted(zip(*map(np.ndarray.tolist, fast))) == sorted(zip(*map(np.ndarray.tolist, slow)))
    right = sum(q < 300 and t == 100 + seen[q] for q, t in zip(*fast))
    assert right >= 250 and len(fast[0]) - right <= 10


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
