"""Keyframes by what the camera saw: none for a still camera but the time cap, few for slow
motion, many for fast motion, some for a pure rotation; and the same path sampled at 30 Hz and
at 10 Hz gives keyframes at nearly the same times. The landmarks are a random cloud of points."""
import numpy as np

from nicer_stream.geometry.camera import project_world as project
from nicer_stream.slam.view_change import KeyframeRule, KeyframeSelector, view_change
from nicer_stream.types import Intrinsics

INTR = Intrinsics(300.0, 300.0, 160.0, 120.0, 320, 240)
RNG = np.random.default_rng(1)
POINTS = np.column_stack([RNG.uniform(-20, 20, 20000), RNG.uniform(-3, 3, 20000), RNG.uniform(-20, 20, 20000)])


def pose(x: float, yaw_deg: float) -> np.ndarray:
    a = np.radians(yaw_deg)
    T = np.eye(4)
    T[:3, :3] = [[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]
    T[0, 3] = x
    return T


def seen(T: np.ndarray) -> tuple[np.ndarray, float]:
    """The landmarks a camera at T sees (M, 3) and their median depth."""
    uv, z = project(T, POINTS, INTR)
    ok = (z > 0.5) & (uv[:, 0] >= 0) & (uv[:, 0] <= 319) & (uv[:, 1] >= 0) & (uv[:, 1] <= 239)
    return POINTS[ok], float(np.median(z[ok]))


def keyframes(speed_m_s: float, yaw_deg_s: float, hz: float, seconds: float = 6.0) -> list[float]:
    """Times of the keyframes of a camera moving along x at `speed_m_s` and turning at `yaw_deg_s`."""
    sel = KeyframeSelector(KeyframeRule(max_gap_s=2.0))
    times = []
    for k in range(int(seconds * hz)):
        t = k / hz
        T = pose(speed_m_s * t, yaw_deg_s * t)
        points, depth = seen(T)
        reason = sel.decide(T, t, depth, INTR)
        if reason:
            sel.taken(k, points, T, t, reason)
            times.append(t)
    return times


def test_static_camera_takes_keyframes_by_the_time_cap_only():
    assert keyframes(0.0, 0.0, 30) == [0.0, 2.0, 4.0]


def test_more_motion_gives_more_keyframes():
    slow, fast = keyframes(0.1, 0.0, 30), keyframes(2.0, 0.0, 30)
    assert len(slow) < len(fast), (slow, fast)
    assert len(fast) >= 8


def test_pure_rotation_takes_keyframes_by_rotation_or_overlap():
    sel = KeyframeSelector(KeyframeRule(max_gap_s=100.0))
    points, d = seen(pose(0, 0))
    sel.taken(0, points, pose(0, 0), 0.0, "first frame")
    assert sel.decide(pose(0, 5), 0.1, d, INTR) is None
    reason = sel.decide(pose(0, 20), 0.2, d, INTR)
    assert reason is not None and ("rotated" in reason or "still in view" in reason), reason
    assert sel.decide(pose(0, 20), 0.2, None, INTR) is None  # without a depth: the time cap only


def test_30_and_10_hz_give_similar_keyframes():
    a, b = keyframes(0.8, 10.0, 30), keyframes(0.8, 10.0, 10)
    assert abs(len(a) - len(b)) <= max(1, 0.2 * len(a)), (a, b)
    # each 10 Hz keyframe within a tenth of a second and a bit of a 30 Hz one
    assert all(min(abs(t - s) for s in a) <= 0.15 for t in b), (a, b)


def test_view_change_measures():
    points, d = seen(pose(0, 0))
    c = view_change(points, pose(0, 0), 0.0, pose(0.5, 0), 0.5, 5.0, INTR)
    expected = seen(pose(0.5, 0))[0]
    assert abs(c.overlap - np.isin(points[:, 0], expected[:, 0]).mean()) < 0.02  # (z > 0.5 in `seen`)
    assert abs(c.baseline - 0.1) < 1e-12 and c.rotation_deg < 1e-6 and c.gap_s == 0.5
    assert view_change(points, pose(0, 0), 0.0, pose(0, 0), 0.0, 5.0, INTR).overlap == 1.0


def test_the_slam_maps_at_its_view_keyframes_and_says_why(tiny_config):
    from dataclasses import replace

    import torch

    from nicer_stream.config import load
    from nicer_stream.slam.events import MapUpdated
    from nicer_stream.slam.system import SlamSystem
    from sources import open_source
    from sources.base import SourceOptions

    torch.manual_seed(0)
    c = load("fast", tiny_config)
    cfg = replace(c, max_side=160, tracking=replace(c.tracking, frontend="classical"),
                  mapping=replace(c.mapping, init="first_frame", keyframes="view", keyframe_max_gap_s=0.3))
    slam = SlamSystem(cfg)
    mapped = []
    for f in open_source("synthetic:room?frames=60", SourceOptions(max_frames=16, max_side=160)):
        mapped += [e.index for e in slam.step(f.without_ground_truth()) if isinstance(e, MapUpdated)]
    reasons = slam.health_summary()["keyframe_reasons"]
    assert set(map(int, reasons)) == set(slam.keyframes), (reasons, slam.keyframes)
    assert reasons[str(slam.keyframes[0])] == "first frame"
    assert 2 <= len(slam.keyframes) < 16
    assert set(mapped[1:]) <= set(slam.keyframes), (mapped, slam.keyframes)  # after the first call
