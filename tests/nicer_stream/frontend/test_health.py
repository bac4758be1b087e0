"""The frontend's own health checks on a synthetic camera over known landmarks: a consistent
pose raises nothing; a stale (frozen) pose, a shrunken translation and a lost frame are each
reported, within a few frames, and only once per episode."""
import numpy as np

from nicer_stream.frontend.health import FrontendHealth, HealthLimits, median_track_motion, reprojection_error
from nicer_stream.geometry.camera import project_world as project
from nicer_stream.types import Intrinsics

INTR = Intrinsics(300.0, 300.0, 160.0, 120.0, 320, 240)
RNG = np.random.default_rng(0)
POINTS = np.column_stack([RNG.uniform(-2, 2, 400), RNG.uniform(-1.5, 1.5, 400), RNG.uniform(3, 5, 400)])


def camera(i: int, step: float = 0.02) -> np.ndarray:
    """T_world_cam of frame i: moving along x, turning slowly about y."""
    a = 0.002 * i
    T = np.eye(4)
    T[:3, :3] = [[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]
    T[0, 3] = step * i
    return T


def observe(T: np.ndarray):
    uv, z = project(T, POINTS, INTR)
    ok = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < 320) & (uv[:, 1] >= 0) & (uv[:, 1] < 240)
    ids = np.flatnonzero(ok)
    return ids, uv[ok], POINTS[ok], float(np.median(z[ok]))


def run(pose_of, frames: int = 40) -> FrontendHealth:
    """Feed frames whose tracks come from the true camera and whose frontend pose is `pose_of(i)`."""
    h = FrontendHealth(HealthLimits())
    for i in range(frames):
        ids, uv, X, _ = observe(camera(i))
        T = pose_of(i)
        depth = None if T is None else float(np.median(project(T, X, INTR)[1]))
        h.check(i, T, ids, uv, uv, X, INTR, depth)
    return h


def test_a_consistent_frontend_raises_nothing():
    assert run(camera).reports == []


def test_a_frozen_pose_is_reported_within_ten_frames_once():
    h = run(lambda i: camera(min(i, 10)))
    kinds = [(r.index, r.kind) for r in h.reports]
    assert kinds and kinds[0][1] in ("reprojection", "frozen") and kinds[0][0] <= 20, kinds
    assert sum(k == "frozen" for _, k in kinds) == 1, kinds  # one report per episode


def test_a_translation_shrunk_tenfold_is_reported_within_ten_frames():
    def shrunk(i):  # from frame 10 on, a tenth of the true translation per frame
        T = camera(i).copy()
        T[0, 3] = 0.02 * min(i, 10) + 0.1 * 0.02 * max(i - 10, 0)
        return T
    h = run(shrunk)
    assert h.reports and h.reports[0].index <= 20, [str(r) for r in h.reports]


def test_a_scale_jump_is_reported():
    """The same camera whose frontend unit drops 3x from frame 20 on (its landmarks with it)."""
    h = FrontendHealth(HealthLimits())
    for i in range(30):
        ids, uv, X, depth = observe(camera(i))
        s = 1.0 if i < 20 else 1 / 3
        T = camera(i).copy()
        T[:3, 3] *= s
        h.check(i, T, ids, uv, uv, X * s, INTR, depth * s)
    assert [r.kind for r in h.reports] and h.reports[0].kind == "scale" and h.reports[0].index == 20


def test_lost_is_reported_once_per_episode_and_not_before_the_start():
    h = run(lambda i: None if i < 3 or 10 <= i < 15 else camera(i))
    assert [(r.index, r.kind) for r in h.reports] == [(10, "lost")]
    assert h.counts()["lost"] == 1


def test_measures():
    T = camera(3)
    ids, uv, X, _ = observe(T)
    assert reprojection_error(T, X, uv, INTR) < 1e-9
    assert median_track_motion(ids, uv, ids, uv + [3.0, 4.0]) == 5.0
