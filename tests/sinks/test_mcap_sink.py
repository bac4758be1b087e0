"""McapSink: write a short recording, decode it with the protobuf decoder, check every topic."""
from __future__ import annotations


import cv2
import numpy as np
import pytest
import torch

from nicer_stream.geometry.se3 import quat_to_matrix, se3_exp
from nicer_stream.types import Intrinsics
from sinks import MultiSink, make_sink
from sinks.base import Sink
from sinks.mcap_sink import McapSink
from tests.sinks.mcap_readback import read_mcap

INTR = Intrinsics(fx=20.0, fy=22.0, cx=7.5, cy=5.25, width=16, height=12)
T0_NS = 1_700_000_000_123_456_789
TETRA_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
TETRA_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def random_poses(n: int, seed: int) -> np.ndarray:
    g = torch.Generator().manual_seed(seed)
    return se3_exp(torch.randn(n, 6, generator=g, dtype=torch.float64)).numpy()


def smooth_rgb(i: int) -> np.ndarray:
    v, u = np.mgrid[0:12, 0:16].astype(np.float32)
    return np.stack([u / 15, v / 11, np.full_like(u, 0.2 + 0.2 * i)], -1)


def pose_matrix(p) -> np.ndarray:
    """foxglove Pose -> (4, 4)."""
    T = np.eye(4)
    q = [p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w]
    T[:3, :3] = quat_to_matrix(torch.tensor(q, dtype=torch.float64)).numpy()
    T[:3, 3] = [p.position.x, p.position.y, p.position.z]
    return T


DEPTH = np.linspace(0.5, 4.0, 12 * 16, dtype=np.float32).reshape(12, 16)
BETA_C = np.random.default_rng(0).random((5, 3))


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("mcap") / "run.mcap"
    poses = random_poses(3, seed=3)
    normal = np.zeros((12, 16, 3), np.float32)
    normal[..., 2] = -1.0
    with McapSink(path) as sink:
        for i, T in enumerate(poses):
            sink.log_frame(i, 0.0, smooth_rgb(i), INTR, T, depth=DEPTH, normal=normal,
                           gt_T_world_cam=poses[0], timestamp_ns=T0_NS + i * 10**8)
            sink.log_scalars(i, {"loss": 0.5 * i})
        sink.log_warning(1, "frontend frozen", "the pose stayed while its tracks moved")
        sink.log_trajectory(poses[:, :3, 3], rotations=poses[:, :3, :3])
        sink.log_mesh(TETRA_V, TETRA_F, np.full((4, 3), 0.5))
        sink.log_beta_voxels(BETA_C, np.arange(5.0), 0.2)
    return read_mcap(path), poses


def test_topics_counts_and_log_times(recording):
    msgs, _ = recording
    per_frame = ["/camera/image", "/camera/calibration", "/camera/depth", "/camera/normal", "/tf",
                 "/camera/pose", "/camera/gt_pose", "/metrics/loss"]
    for topic in per_frame:
        assert [t for t, _ in msgs[topic]] == [T0_NS + i * 10**8 for i in range(3)], topic
    for topic in ["/trajectory", "/mesh", "/beta"]:
        assert [t for t, _ in msgs[topic]] == [T0_NS + 2 * 10**8], topic  # last frame's time
    _, img = msgs["/camera/image"][0]
    assert img.timestamp.ToNanoseconds() == T0_NS


def test_tracking_warnings_are_log_messages_at_their_frame_time(recording):
    msgs, _ = recording
    (t, log), = msgs["/tracking/warnings"]
    assert t == T0_NS + 10**8
    assert log.message == "frame 1: frontend frozen: the pose stayed while its tracks moved"
    assert log.level == 3  # foxglove.Log.WARNING


def test_poses_round_trip(recording):
    msgs, poses = recording
    for (_, pose), (_, tf), T in zip(msgs["/camera/pose"], msgs["/tf"], poses):
        assert pose.frame_id == "world"
        np.testing.assert_allclose(pose_matrix(pose.pose), T, atol=1e-9)
        # FrameTransform world -> camera carries the camera pose in the world (camera-to-world).
        assert (tf.parent_frame_id, tf.child_frame_id) == ("world", "camera")
        np.testing.assert_allclose([tf.translation.x, tf.translation.y, tf.translation.z], T[:3, 3], atol=1e-9)
    traj = msgs["/trajectory"][0][1]
    assert len(traj.poses) == 3
    for p, T in zip(traj.poses, poses):
        np.testing.assert_allclose(pose_matrix(p), T, atol=1e-9)
    np.testing.assert_allclose(pose_matrix(msgs["/camera/gt_pose"][2][1].pose), poses[0], atol=1e-9)


def test_images_and_calibration(recording):
    msgs, _ = recording
    img = msgs["/camera/image"][1][1]
    assert img.format == "jpeg"
    bgr = cv2.imdecode(np.frombuffer(img.data, np.uint8), cv2.IMREAD_COLOR)
    assert np.abs(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB) / 255.0 - smooth_rgb(1)).mean() < 0.02
    cal = msgs["/camera/calibration"][0][1]
    np.testing.assert_allclose(np.reshape(cal.K, (3, 3)), INTR.matrix())  # row-major
    np.testing.assert_allclose(np.reshape(cal.P, (3, 4))[:, :3], INTR.matrix())
    assert (cal.width, cal.height) == (16, 12)
    dep = msgs["/camera/depth"][0][1]
    assert (dep.encoding, dep.step) == ("32FC1", 64)
    np.testing.assert_array_equal(np.frombuffer(dep.data, "<f4").reshape(12, 16), DEPTH)
    nrm = cv2.imdecode(np.frombuffer(msgs["/camera/normal"][0][1].data, np.uint8), cv2.IMREAD_COLOR)
    assert np.abs(nrm[..., ::-1].astype(int) - [128, 128, 0]).max() <= 1  # (n + 1) / 2 of (0, 0, -1)


def test_mesh_beta_scalars(recording):
    msgs, _ = recording
    ent = msgs["/mesh"][0][1].entities[0]
    tri = ent.triangles[0]
    assert (ent.frame_id, len(tri.points), list(tri.indices)) == ("world", 4, TETRA_F.reshape(-1).tolist())
    np.testing.assert_array_equal([[p.x, p.y, p.z] for p in tri.points], TETRA_V)
    assert [(c.r, c.a) for c in tri.colors] == [(pytest.approx(128 / 255), 1.0)] * 4  # 0.5 -> uint8 128
    cloud = msgs["/beta"][0][1]
    data = np.frombuffer(cloud.data, "<f4").reshape(-1, cloud.point_stride // 4)
    assert [f.name for f in cloud.fields] == ["x", "y", "z", "beta"]
    np.testing.assert_allclose(data[:, :3], BETA_C, atol=1e-6)
    np.testing.assert_array_equal(data[:, 3], np.arange(5.0))
    assert [m.value for _, m in msgs["/metrics/loss"]] == [0.0, 0.5, 1.0]


def test_exception_mid_run_and_close_twice(tmp_path):
    path = tmp_path / "crash.mcap"
    sink = McapSink(path)
    with pytest.raises(KeyError):
        with sink:
            sink.log_frame(0, 0.25, smooth_rgb(0), INTR, np.eye(4))
            {}["boom"]
    sink.close()  # second close is a no-op
    msgs = read_mcap(path)
    assert len(msgs["/camera/image"]) == 1 and msgs["/tf"][0][0] == 250_000_000
    with pytest.raises(RuntimeError):
        sink.log_pose(1, 1.0, np.eye(4))


def test_frames_are_on_disk_before_close(tmp_path):
    """Each frame is flushed as a chunk: a crash (no close) loses nothing already logged."""
    path = tmp_path / "open.mcap"
    sink = McapSink(path)
    for i in range(2):
        sink.log_frame(i, float(i), smooth_rgb(i), INTR, np.eye(4))
    from mcap.reader import NonSeekingReader

    with open(path, "rb") as f:
        seen = []
        try:
            for _, ch, _ in NonSeekingReader(f).iter_messages(log_time_order=False):
                seen.append(ch.topic)
        except Exception:
            pass  # no footer yet: the stream ends early
    assert seen.count("/camera/image") == 2
    sink.close()


class _FailingClose(Sink):
    def log_pose(self, *a, **k): pass
    def log_frame(self, *a, **k): pass
    def log_trajectory(self, *a, **k): pass
    def log_mesh(self, *a, **k): pass
    def log_beta_voxels(self, *a, **k): pass
    def log_map_render(self, *a, **k): pass
    def log_keyframes(self, *a, **k): pass
    def log_scalars(self, *a, **k): pass
    def close(self): raise OSError("disk full")


def test_multisink(tmp_path):
    sink = make_sink(f"mcap:{tmp_path / 'a.mcap'},rerun:{tmp_path / 'a.rrd'}")
    assert isinstance(sink, MultiSink) and len(sink.sinks) == 2
    sink.log_pose(0, 1.0, np.eye(4))
    sink.close()
    assert len(read_mcap(tmp_path / "a.mcap")["/tf"]) == 1 and (tmp_path / "a.rrd").stat().st_size > 0
    # A sink failing to close does not stop the others from finalising their files.
    multi = MultiSink([_FailingClose(), McapSink(tmp_path / "b.mcap")])
    multi.log_pose(0, 1.0, np.eye(4))
    with pytest.raises(OSError):
        multi.close()
    assert len(read_mcap(tmp_path / "b.mcap")["/camera/pose"]) == 1


def test_real_replica_frame(tmp_path, replica_dir):
    """A real image and depth survive the round trip (JPEG error only; depth exact)."""
    rgb = cv2.cvtColor(cv2.imread(str(replica_dir / "results" / "frame000000.jpg")), cv2.COLOR_BGR2RGB)
    rgb = cv2.resize(rgb, (120, 68), interpolation=cv2.INTER_AREA).astype(np.float32) / 255.0
    depth = cv2.imread(str(replica_dir / "results" / "depth000000.png"), cv2.IMREAD_UNCHANGED) / 6553.5
    depth = cv2.resize(depth.astype(np.float32), (120, 68), interpolation=cv2.INTER_NEAREST)
    T = np.loadtxt(replica_dir / "traj.txt", max_rows=1).reshape(4, 4)
    intr = Intrinsics(600.0, 600.0, 599.5, 339.5, 1200, 680).resized(120, 68)
    with McapSink(tmp_path / "r.mcap") as sink:
        sink.log_frame(0, 0.0, rgb, intr, T, depth=depth)
    msgs = read_mcap(tmp_path / "r.mcap")
    back = cv2.imdecode(np.frombuffer(msgs["/camera/image"][0][1].data, np.uint8), cv2.IMREAD_COLOR)
    assert np.abs(back[..., ::-1] / 255.0 - rgb).mean() < 0.03
    np.testing.assert_array_equal(np.frombuffer(msgs["/camera/depth"][0][1].data, "<f4").reshape(68, 120), depth)
    np.testing.assert_allclose(pose_matrix(msgs["/camera/pose"][0][1].pose), T, atol=1e-9)
    np.testing.assert_allclose(np.reshape(msgs["/camera/calibration"][0][1].K, (3, 3)), intr.matrix())


def test_rerun_imports_our_mcap_with_images_and_transforms(tmp_path):
    """`rerun mcap convert` (Rerun's own MCAP importer) reads the images, depth, calibration and
    transforms of our MCAP: the poses come out equal to what was logged."""
    import subprocess
    import sys
    from pathlib import Path

    from sinks.readback import read_rrd_columns

    path, poses = tmp_path / "run.mcap", random_poses(3, seed=5)
    with McapSink(path) as sink:
        for i, T in enumerate(poses):
            sink.log_frame(i, 0.0, smooth_rgb(i), INTR, T, depth=DEPTH, timestamp_ns=T0_NS + i * 10**8)
    rerun = Path(sys.executable).with_name("rerun")
    res = subprocess.run([str(rerun), "mcap", "convert", str(path), "-o", str(tmp_path / "run.rrd")],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    cols = read_rrd_columns(tmp_path / "run.rrd")
    assert len(cols["/camera/image"]["EncodedImage:blob"]) == 3
    assert len(cols["/camera/depth"]["Image:buffer"]) == 3
    assert len(cols["/camera/calibration"]["Pinhole:image_from_camera"]) == 3
    tf = np.asarray([np.asarray(t).reshape(3) for t in cols["/tf"]["Transform3D:translation"]])
    np.testing.assert_allclose(tf, poses[:, :3, 3], atol=1e-5)


def test_images_every_nth_frame_downsized_and_every_pose(tmp_path):
    from sinks.options import SinkOptions

    poses = random_poses(5, seed=5)
    with make_sink(f"mcap:{tmp_path / 's.mcap'}?images_every=2&image_side=8") as sink:
        for i, T in enumerate(poses):
            sink.log_frame(i, 0.1 * i, smooth_rgb(i), INTR, T, depth=DEPTH)
    assert sink.options == SinkOptions(2, 8)
    msgs = read_mcap(tmp_path / "s.mcap")
    assert len(msgs["/camera/pose"]) == 5
    times = [t for t, _ in msgs["/camera/pose"]]
    assert [t for t, _ in msgs["/camera/image"]] == [times[0], times[2], times[4]] == [t for t, _ in msgs["/camera/depth"]]
    cal = msgs["/camera/calibration"][0][1]
    assert (cal.width, cal.height) == (8, 6)
    np.testing.assert_allclose(np.reshape(cal.K, (3, 3)), INTR.resized(8, 6).matrix())
    img = cv2.imdecode(np.frombuffer(msgs["/camera/image"][1][1].data, np.uint8), cv2.IMREAD_COLOR)
    assert img.shape == (6, 8, 3)
