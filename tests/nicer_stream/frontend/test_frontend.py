"""The classical frontend on the synthetic scenes: with the first poses given (as the SLAM's
start gives them), PnP on triangulated KLT tracks follows the camera; bounded memory."""
import numpy as np
import pytest

from nicer_stream.config import FrontendConfig
from nicer_stream.frontend.frontend import ClassicalFrontend
from nicer_stream.geometry.se3 import rotation_angle
from sources import open_source
from sources.base import SourceOptions

import torch


def _err(T_gt, T):
    d = np.linalg.inv(T_gt) @ T
    return float(np.linalg.norm(d[:3, 3])), float(np.degrees(float(rotation_angle(torch.from_numpy(d[:3, :3])))))


# Largest rotation error of a frame, degrees. The 90-frame street stays under 1 degree on the AMD
# CPU the frontend was tuned on; on an Intel CPU with AVX-512 (OpenCV's SIFT takes other SIMD
# paths there) it reaches 2.3 degrees at frame 56, on the checkered facades.
MAX_ROT_DEG = 3.0


@pytest.mark.parametrize("uri, frames, bound", [("synthetic:room?frames=120", 30, 0.02),
                                                ("synthetic:street?frames=40&grey=1", 25, 0.02),
                                                ("synthetic:street?frames=90", 90, 0.03)])
def test_frontend_follows_the_camera_from_two_known_poses(uri, frames, bound):
    """Frames 0 and 5 posed from ground truth, every later frame estimated by PnP and then fed
    back as trusted (what the SLAM does without photometric refinement): the error stays small
    against the path length (largest error, unaligned: on the 90-frame street that is mostly
    scale drift, 2.7%). That street drives past checkered facades (frames 55-85), where
    unguided matching and a keyframe-only BA let the rotation drift 15 degrees."""
    src = list(open_source(uri, SourceOptions(max_frames=frames)))
    # 400 features, as these scenes were tuned with: with the default 1000 the street's checkered
    # facades give more near-twin matches (largest error 0.53 m over 24 m; docs/decisions.md).
    fe = ClassicalFrontend(FrontendConfig(corners=400))
    path = sum(np.linalg.norm(b.gt_pose[:3, 3] - a.gt_pose[:3, 3]) for a, b in zip(src, src[1:]))
    for f in src[:6]:
        fe.observe(f.index, f.rgb, f.intrinsics)
    fe.set_pose(0, src[0].gt_pose)
    fe.set_pose(5, src[5].gt_pose)
    errs = []
    for k, f in enumerate(src[1:5], start=1):  # the frames held before the second view
        est = fe.estimate(f.index, src[k - 1].gt_pose)
        assert est is not None and est.inliers >= 30
        errs.append(_err(f.gt_pose, est.T_world_cam)[0])
    T_prev = src[5].gt_pose
    for k, f in enumerate(src[6:], start=6):
        fe.observe(f.index, f.rgb, f.intrinsics)
        est = fe.estimate(f.index, T_prev)
        assert est is not None, f"frame {f.index}: no pose"
        t_err, r_err = _err(f.gt_pose, est.T_world_cam)
        errs.append(t_err)
        assert r_err < MAX_ROT_DEG, (f.index, r_err)
        fe.set_pose(f.index, est.T_world_cam)
        T_prev = est.T_world_cam
    assert max(errs) < bound * path, (max(errs), path)
    assert len(fe.obs) <= fe.cfg.window


def test_untrusted_pose_is_not_triangulated_from():
    src = list(open_source("synthetic:room?frames=120", SourceOptions(max_frames=8)))
    fe = ClassicalFrontend(FrontendConfig())
    for f in src:
        fe.observe(f.index, f.rgb, f.intrinsics)
    fe.set_pose(0, src[0].gt_pose)
    fe.set_pose(7, src[7].gt_pose @ np.diag([1.0, 1.0, 1.0, 1.0]), trusted=False)
    assert not fe.landmarks and 7 not in fe.poses
    fe.set_pose(7, src[7].gt_pose)
    assert len(fe.landmarks) > 50
    X = np.stack(list(fe.landmarks.values()))
    # landmarks lie in the room (GT geometry): inside its bounds
    lo, hi = src[0].gt_pose[:3, 3] - 10, src[0].gt_pose[:3, 3] + 10
    assert ((X > lo) & (X < hi)).all()


@pytest.mark.parametrize("orbit_frames, every", [(40, 1), (800, 4)])
def test_bundle_adjustment_frames_keep_a_baseline(orbit_frames, every):
    """The room's orbit split into 40 frames moves ~8 cm a frame (>2% of its depth): every frame
    joins the bundle adjustment. Split into 800, ~4 mm a frame: a frame in 2 or more joins (one
    in 4 on average here), so the frames the BA holds fixed are not a few millimetres apart."""
    src = list(open_source(f"synthetic:room?frames={orbit_frames}", SourceOptions(max_frames=24)))
    fe = ClassicalFrontend(FrontendConfig())
    for f in src:
        fe.observe(f.index, f.rgb, f.intrinsics)
        fe.set_pose(f.index, f.gt_pose)
    joined = np.diff(fe.posed[1:])  # after the first two, which always join
    assert len(fe.posed) >= 3
    if every == 1:
        assert joined.max() == 1, fe.posed
    else:
        assert joined.min() >= 2 and len(fe.posed) <= len(src) // every, fe.posed


def test_the_fallback_start_takes_a_pair_below_the_usual_parallax():
    """Room frames 0 and 2 (4 cm apart, ~1.2 degrees of parallax): below the start's 2 degrees, so
    the usual start finds nothing; the fallback (`fallback_parallax_deg = 0.5`) gives the second
    view in GT's direction of travel (1.1 degrees off here), reports its parallax and keeps the
    scale convention; a fallback threshold of 0 (the default) turns it off. The essential matrix
    alone (`start_ba` off): the two-view adjustment moved this narrow pair's direction to 5.1
    degrees from GT (measured), a case where it does not help (docs/priors.md)."""
    from dataclasses import replace

    src = list(open_source("synthetic:room?frames=120", SourceOptions(max_frames=3)))
    cfg = replace(FrontendConfig(), fallback_parallax_deg=0.5, start_ba=False, corners=400)  # as tuned
    fe = ClassicalFrontend(cfg)
    off = ClassicalFrontend(replace(cfg, fallback_parallax_deg=0.0))
    for f in src:
        fe.observe(f.index, f.rgb, f.intrinsics)
        off.observe(f.index, f.rgb, f.intrinsics)
    assert fe.two_view(0, 2, 2.0) is None
    got = fe.two_view(0, 2, 2.0, fallback=True)
    assert got is not None and got.inliers >= cfg.min_inliers
    assert cfg.fallback_parallax_deg <= got.parallax_deg < cfg.init_parallax_deg
    rel = np.linalg.inv(src[0].gt_pose) @ src[2].gt_pose
    t = got.T_world_second[:3, 3]
    cos = t @ rel[:3, 3] / np.linalg.norm(t) / np.linalg.norm(rel[:3, 3])
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))) < 5.0
    assert abs(np.median(got.points[:, 2]) - 2.0) < 1e-6  # the first view's median depth: the map's unit
    assert off.two_view(0, 2, 2.0, fallback=True) is None


def test_the_frontend_on_the_sources_larger_image_places_frames_closer_to_the_truth(replica_dir):
    """The Replica clip at the map's 320 px and the frontend on its 1200 px grey copy
    (`Frame.detail`): frames 0 and 5 posed from GT, 6-12 by PnP fed back as trusted. At 1200 px the
    features sit to a quarter of a 320 px pixel: the largest position error is at most half of the
    320 px frontend's (measured 2026-12-05: ~5x smaller on the whole clip, docs/priors.md)."""
    src = list(open_source(f"replica:{replica_dir}", SourceOptions(max_frames=13, max_side=320, detail_side=1200)))
    assert src[0].detail.grey.shape == (680, 1200)
    worst = {}
    for name, view in (("map", lambda f: (f.rgb, f.intrinsics)), ("detail", lambda f: (f.detail.grey, f.detail.intrinsics))):
        fe = ClassicalFrontend(FrontendConfig())
        for f in src[:6]:
            fe.observe(f.index, *view(f))
        fe.set_pose(0, src[0].gt_pose)
        fe.set_pose(5, src[5].gt_pose)
        errs, T_prev = [], src[5].gt_pose
        for f in src[6:]:
            fe.observe(f.index, *view(f))
            est = fe.estimate(f.index, T_prev)
            assert est is not None, (name, f.index)
            errs.append(_err(f.gt_pose, est.T_world_cam)[0])
            fe.set_pose(f.index, est.T_world_cam)
            T_prev = est.T_world_cam
        worst[name] = max(errs)
    assert worst["detail"] <= 0.5 * worst["map"], worst


def test_the_start_refined_by_a_two_view_adjustment_is_closer_to_the_truth(replica_dir):
    """Replica frames 0 and 10 (12 cm apart at ~2.7 m) on the 1200 px image: the essential
    matrix alone leaves the second view 0.2 degrees and its direction of travel 4.5 degrees off
    GT (measured); the two-view adjustment (`start_ba`, the default) brings them to 0.02 / 0.4
    degrees. Those views stay fixed in every later adjustment, so this error would stay in the
    trajectory and bias every stereo pair (5% shorter depth on this clip)."""
    from dataclasses import replace

    src = list(open_source(f"replica:{replica_dir}", SourceOptions(max_frames=11, max_side=320, detail_side=1200)))
    rel = np.linalg.inv(src[0].gt_pose) @ src[10].gt_pose
    errs = {}
    for on in (True, False):
        fe = ClassicalFrontend(replace(FrontendConfig(), start_ba=on))
        for f in src:
            fe.observe(f.index, f.detail.grey, f.detail.intrinsics)
        got = fe.two_view(0, 10, 2.0)
        T = got.T_world_second
        t = T[:3, 3]
        cos = t @ rel[:3, 3] / np.linalg.norm(t) / np.linalg.norm(rel[:3, 3])
        errs[on] = (_err(rel, T)[1], float(np.degrees(np.arccos(np.clip(cos, -1, 1)))))
        assert abs(np.median(got.points[:, 2]) - 2.0) < 0.05  # the first view's depth still sets the unit
    assert errs[True][0] < 0.08 and errs[True][1] < 1.5, errs
    assert errs[True][0] < 0.5 * errs[False][0] and errs[True][1] < 0.5 * errs[False][1], errs


def test_holding_the_scale_keeps_every_projection_and_the_first_baseline():
    """`hold_scale` rescales an adjusted window about its first camera so its first two cameras
    are as far apart as before the adjustment; no camera sees any point move."""
    from nicer_stream.frontend.frontend import hold_scale
    from nicer_stream.geometry.camera import project_world as project
    from nicer_stream.geometry.se3 import se3_exp
    from nicer_stream.types import Intrinsics

    rng = np.random.default_rng(0)
    intr = Intrinsics(300.0, 300.0, 160.0, 120.0, 320, 240)
    poses = [se3_exp(torch.tensor(rng.normal(0, 0.2, 6))).double().numpy() for _ in range(4)]
    before = [se3_exp(torch.tensor(rng.normal(0, 0.2, 6))).double().numpy() for _ in range(4)]
    X = rng.normal(0, 1, (50, 3)) + np.array([0.0, 0.0, 5.0])
    out, Y = hold_scale(before, poses, X)
    np.testing.assert_allclose(out[0], poses[0])
    d = lambda P: np.linalg.norm(P[1][:3, 3] - P[0][:3, 3])
    assert abs(d(out) - d(before)) < 1e-12
    for T, U in zip(poses, out):
        np.testing.assert_allclose(U[:3, :3], T[:3, :3])
        uv0, z0 = project(T, X, intr)
        uv1, z1 = project(U, Y, intr)
        np.testing.assert_allclose(uv1[z0 > 0], uv0[z0 > 0], atol=1e-9)


def test_a_pinned_frame_outlives_the_window():
    """The first view of a start still waiting for its second keeps its observations however
    long the wait (the window drops every other old frame)."""
    from dataclasses import replace
    fe = ClassicalFrontend(replace(FrontendConfig(), window=4))
    for f in open_source("synthetic:room?frames=120", SourceOptions(max_frames=9, max_side=160)):
        fe.observe(f.index, f.rgb, f.intrinsics)
        fe.pinned = {0}
    assert sorted(fe.obs) == [0, 5, 6, 7, 8]


def test_landmarks_seeded_from_depth_place_a_frame_that_triangulation_cannot():
    """One posed frame and no second: no landmark can be triangulated, so a later frame gets no
    pose. Seeded from the first frame's depth (here the scene's own), its tracks become landmarks
    at the right places and PnP places the later frame."""
    src = list(open_source("synthetic:room?frames=120", SourceOptions(max_frames=4)))
    fe = ClassicalFrontend(FrontendConfig(corners=400))
    for f in src[:3]:
        fe.observe(f.index, f.rgb, f.intrinsics)
    fe.set_pose(0, src[0].gt_pose)
    assert fe.estimate(2, src[0].gt_pose) is None

    def depth_at(T, uv):
        assert np.array_equal(T, src[0].gt_pose)
        z = src[0].gt_depth[np.round(uv[:, 1]).astype(int), np.round(uv[:, 0]).astype(int)].astype(float)
        z[::7] = np.nan  # where the map does not know
        return z

    n, ratio = fe.seed_landmarks(0, depth_at)
    assert n > 100 and len(fe.landmarks) == n and np.isnan(ratio)  # none of its own to compare with
    uv, X = fe.landmark_observations(0)
    T_cam_world = np.linalg.inv(src[0].gt_pose)
    Xc = X @ T_cam_world[:3, :3].T + T_cam_world[:3, 3]
    intr = src[0].intrinsics
    assert np.allclose(Xc[:, 0] / Xc[:, 2] * intr.fx + intr.cx, uv[:, 0], atol=1e-6)
    assert fe.seed_landmarks(0, depth_at)[0] == 0  # enough landmarks now
    est = fe.estimate(2, src[0].gt_pose)
    assert est is not None
    assert _err(src[2].gt_pose, est.T_world_cam)[0] < 0.02


@pytest.mark.parametrize("rescale", [False, True])
def test_a_map_depth_at_another_scale_rescales_the_frontend_or_seeds_nothing(rescale):
    """A frame with landmarks of its own and a map depth twice theirs: the map's scale is not the
    frontend's. With `map_rescale` the frontend's landmarks and window move to the map's scale
    about the frame's centre (its tracks reproject as before) and the rest is seeded; without, no
    landmark from the map mixes a second scale in."""
    src = list(open_source("synthetic:room?frames=120", SourceOptions(max_frames=1)))
    fe = ClassicalFrontend(FrontendConfig(corners=400, map_landmarks_below=10_000, map_rescale=rescale))
    fe.observe(0, src[0].rgb, src[0].intrinsics)
    T = src[0].gt_pose.copy()
    fe.set_pose(0, T)

    def depth_at(factor, every):
        def f(T, uv):
            z = src[0].gt_depth[np.round(uv[:, 1]).astype(int), np.round(uv[:, 0]).astype(int)].astype(float)
            z[np.arange(len(z)) % every != 0] = np.nan
            return z * factor
        return f

    n0 = fe.seed_landmarks(0, depth_at(1.0, 3))[0]  # a third of its tracks
    assert n0 > 50
    before = dict(fe.landmarks)
    n, ratio = fe.seed_landmarks(0, depth_at(2.0, 1))
    assert abs(ratio - 0.5) < 1e-6
    if not rescale:
        assert n == 0 and len(fe.landmarks) == n0
        n, ratio = fe.seed_landmarks(0, depth_at(1.1, 1))  # within map_landmark_scale: the rest
        assert n > 0 and abs(ratio - 1 / 1.1) < 1e-6 and len(fe.landmarks) == n0 + n
    else:
        assert n > 0 and len(fe.landmarks) == n0 + n
        c = T[:3, 3]
        for t, X in before.items():
            assert np.allclose(fe.landmarks[t], c + 2 * (X - c))
        assert np.allclose(fe.poses[0], T)  # the centre of the scaling
        assert np.isclose(fe.seed_landmarks(0, depth_at(2.0, 1), check_scale=True)[1], 1.0)
