"""RerunSink: write a short recording, read it back with RrdReader, check what was stored."""
from __future__ import annotations

import sys

import cv2
import numpy as np
import pytest
import torch

from nicer_stream.errors import UserError
from nicer_stream.geometry.se3 import quat_to_matrix, se3_exp
from nicer_stream.types import Intrinsics
from sinks import make_sink
from sinks.options import SinkOptions
from sinks.readback import read_rrd_columns as read_columns
from sinks.rerun_sink import RerunSink

INTR = Intrinsics(fx=20.0, fy=22.0, cx=7.5, cy=5.25, width=16, height=12)
T0_NS = 1_700_000_000_123_456_789  # epoch time: a float in seconds would lose the last digits


def random_poses(n: int, seed: int) -> np.ndarray:
    g = torch.Generator().manual_seed(seed)
    return se3_exp(torch.randn(n, 6, generator=g, dtype=torch.float64)).numpy()


def smooth_rgb(i: int) -> np.ndarray:
    """(12, 16, 3) float32 gradient: JPEG reproduces it closely."""
    v, u = np.mgrid[0:12, 0:16].astype(np.float32)
    return np.stack([u / 15, v / 11, np.full_like(u, 0.2 + 0.2 * i)], -1)


TETRA_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
TETRA_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
TETRA_C = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [10, 20, 30]], dtype=np.uint8)


def write_recording(path, poses) -> None:
    depth = np.linspace(0.5, 4.0, 12 * 16, dtype=np.float32).reshape(12, 16)
    normal = np.zeros((12, 16, 3), np.float32)
    normal[..., 2] = -1.0
    sink = RerunSink(path, recording_id="test", log_time=False)
    for i, T in enumerate(poses):
        sink.log_frame(i, 0.0, smooth_rgb(i), INTR, T, depth=depth, normal=normal,
                       gt_T_world_cam=T, timestamp_ns=T0_NS + i * 10**8)
        sink.log_scalars(i, {"loss": 0.5 * i, "psnr_db": 20.0 + i})
    sink.log_warning(2, "disagreement", "the frontend and the map disagree on 5 refined frames in a row")
    sink.log_trajectory(poses[:, :3, 3])
    sink.log_mesh(TETRA_V, TETRA_F, TETRA_C)
    sink.log_beta_voxels(np.random.default_rng(0).random((5, 3)), np.arange(5.0), 0.2)
    sink.close()


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("rr") / "run.rrd"
    poses = random_poses(3, seed=1)
    write_recording(path, poses)
    return read_columns(path), poses


def test_entities_present(recording):
    cols, _ = recording
    for e in ["/world/camera", "/world/camera/image", "/world/camera/image/rgb", "/world/camera/image/depth",
              "/world/camera/image/normal", "/world/camera_gt", "/world/trajectory/estimate",
              "/world/trajectory/gt/00000", "/world/trajectory/tracked/00000", "/world/mesh", "/world/beta", "/metrics/loss", "/metrics/psnr_db"]:
        assert e in cols, e


def test_camera_pose_and_timelines_round_trip(recording):
    cols, poses = recording
    cam = cols["/world/camera"]
    assert cam["frame"] == [0, 1, 2]
    assert cam["sensor_time"] == [T0_NS + i * 10**8 for i in range(3)]  # ns exact
    for T, t, q in zip(poses, cam["Transform3D:translation"], cam["Transform3D:quaternion"]):
        np.testing.assert_allclose(t[0], T[:3, 3], atol=1e-5)  # stored as float32
        R = quat_to_matrix(torch.tensor(q[0], dtype=torch.float64)).numpy()
        np.testing.assert_allclose(R, T[:3, :3], atol=1e-6)  # camera-to-world rotation


def test_pinhole_is_column_major_K(recording):
    cols, _ = recording
    pin = cols["/world/camera/image"]
    K = np.asarray(pin["Pinhole:image_from_camera"][0][0]).reshape(3, 3).T
    np.testing.assert_allclose(K, INTR.matrix(), atol=1e-6)
    assert pin["Pinhole:resolution"][0][0] == [16.0, 12.0]


def test_images_decode(recording):
    cols, _ = recording
    blob = bytes(cols["/world/camera/image/rgb"]["EncodedImage:blob"][1][0])
    rgb = cv2.cvtColor(cv2.imdecode(np.frombuffer(blob, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    assert np.abs(rgb / 255.0 - smooth_rgb(1)).mean() < 0.02  # JPEG error only
    dep = np.frombuffer(bytes(cols["/world/camera/image/depth"]["DepthImage:buffer"][0][0]), np.float32)
    np.testing.assert_array_equal(dep, np.linspace(0.5, 4.0, 192, dtype=np.float32))  # lossless
    assert cols["/world/camera/image/depth"]["DepthImage:meter"][0] == [1.0]


def test_mesh_and_beta(recording):
    cols, _ = recording
    mesh = cols["/world/mesh"]
    assert len(mesh["Mesh3D:vertex_positions"][0]) == 4
    np.testing.assert_array_equal(np.asarray(mesh["Mesh3D:triangle_indices"][0]), TETRA_F)
    packed = [(int(r) << 24) | (int(g) << 16) | (int(b) << 8) | 0xFF for r, g, b in TETRA_C]
    assert mesh["Mesh3D:vertex_colors"][0] == packed  # u32 0xRRGGBBAA
    beta = cols["/world/beta"]
    assert len(beta["Points3D:positions"][0]) == 5
    assert beta["Points3D:radii"][0] == pytest.approx([0.1])
    assert len(set(beta["Points3D:colors"][0])) == 5  # distinct betas -> distinct colours


def test_tracking_warnings_are_text_logs_at_their_frame(recording):
    cols, _ = recording
    warn = cols["/tracking/warnings"]
    assert warn["frame"] == [2]
    text = str(warn["TextLog:text"][0])
    assert "frame 2: disagreement: the frontend and the map disagree" in text, warn
    assert "WARN" in str(warn["TextLog:level"][0])


def test_scalars_and_trajectories(recording):
    cols, poses = recording
    assert [v[0] for v in cols["/metrics/loss"]["Scalars:scalars"]] == [0.0, 0.5, 1.0]
    assert cols["/metrics/loss"]["frame"] == [0, 1, 2]
    strip = np.asarray(cols["/world/trajectory/estimate"]["LineStrips3D:strips"][0][0])
    np.testing.assert_allclose(strip, poses[:, :3, 3], atol=1e-5)
    gt = np.asarray(cols["/world/trajectory/gt/00000"]["LineStrips3D:strips"][-1][0])
    np.testing.assert_allclose(gt, poses[:, :3, 3], atol=1e-5)  # gt strip written at close


@pytest.mark.parametrize("name", ["tracked", "gt"])
def test_trajectories_are_logged_as_they_grow_in_joined_pieces_linear_in_frames(tmp_path, name):
    poses = random_poses(7, seed=3)
    sink = RerunSink(tmp_path / "gt.rrd", log_time=False, strip_every=3)
    for i, T in enumerate(poses):
        sink.log_pose(i, 0.1 * i, T, gt_T_world_cam=T @ se3_exp(torch.full((6,), 0.1, dtype=torch.float64)).numpy())
    sink.close()
    cols = read_columns(tmp_path / "gt.rrd")
    names = sorted(e for e in cols if e.startswith(f"/world/trajectory/{name}/"))
    pieces = [np.asarray(cols[e]["LineStrips3D:strips"][-1][0]) for e in names]
    assert [len(p) for p in pieces] == [3, 4, 2]  # 3 new points each (+ the joint), the rest at close
    for a, b in zip(pieces, pieces[1:]):
        np.testing.assert_array_equal(a[-1], b[0])
    joined = np.concatenate([pieces[0]] + [p[1:] for p in pieces[1:]])
    logged = np.stack(cols["/world/camera" if name == "tracked" else "/world/camera_gt"]["Transform3D:translation"])[:, 0]
    np.testing.assert_allclose(joined, logged, atol=1e-6)
    # Each piece is logged when its last frame comes: the line grows along the frame timeline.
    assert [cols[e]["frame"] for e in names] == [[2], [5], [6]]
    assert "/world/trajectory/estimate" not in cols  # the final strip comes from log_trajectory only


def test_input_images_every_nth_frame_downsized_with_their_intrinsics(tmp_path):
    poses = random_poses(7, seed=4)
    sink = RerunSink(tmp_path / "s.rrd", log_time=False, options=SinkOptions(images_every=3, image_side=8))
    assert [sink.wants_image(i) for i in range(4)] == [True, False, False, True]
    depth = np.arange(12 * 16, dtype=np.float32).reshape(12, 16)
    for i, T in enumerate(poses):
        sink.log_frame(i, 0.1 * i, smooth_rgb(i), INTR, T, depth=depth)
    sink.close()
    cols = read_columns(tmp_path / "s.rrd")
    assert cols["/world/camera"]["frame"] == list(range(7))  # every pose
    assert cols["/world/camera/image/rgb"]["frame"] == [0, 3, 6] == cols["/world/camera/image/depth"]["frame"]
    pin = cols["/world/camera/image"]
    assert pin["Pinhole:resolution"][0][0] == [8.0, 6.0]
    K = np.asarray(pin["Pinhole:image_from_camera"][0][0]).reshape(3, 3).T
    np.testing.assert_allclose(K, INTR.resized(8, 6).matrix(), atol=1e-6)
    blob = bytes(cols["/world/camera/image/rgb"]["EncodedImage:blob"][1][0])
    rgb = cv2.cvtColor(cv2.imdecode(np.frombuffer(blob, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    small = cv2.resize(smooth_rgb(3), (8, 6), interpolation=cv2.INTER_AREA)
    assert rgb.shape == (6, 8, 3) and np.abs(rgb / 255.0 - small).mean() < 0.03  # frame 3's image, JPEG error only
    dep = np.frombuffer(bytes(cols["/world/camera/image/depth"]["DepthImage:buffer"][0][0]), np.float32)
    assert set(dep) <= set(depth.ravel())  # nearest pixels: no depth averaged across an edge


def test_close_twice_and_log_after_close(tmp_path):
    sink = RerunSink(tmp_path / "a.rrd", log_time=False)
    sink.log_pose(0, 1.0, np.eye(4))
    sink.close()
    sink.close()
    with pytest.raises(RuntimeError):
        sink.log_pose(1, 2.0, np.eye(4))
    assert read_columns(tmp_path / "a.rrd")["/world/camera"]["frame"] == [0]


def test_exception_mid_run_keeps_file(tmp_path):
    poses = random_poses(2, seed=2)
    with pytest.raises(ZeroDivisionError):
        with RerunSink(tmp_path / "crash.rrd", log_time=False) as sink:
            for i, T in enumerate(poses):
                sink.log_frame(i, i * 0.1, smooth_rgb(i), INTR, T)
            1 / 0
    cols = read_columns(tmp_path / "crash.rrd")
    assert cols["/world/camera"]["frame"] == [0, 1]
    assert len(cols["/world/camera/image/rgb"]["EncodedImage:blob"]) == 2


def test_make_sink_specs(tmp_path, monkeypatch):
    sink = make_sink(f"rerun:{tmp_path / 'sub' / 'x.rrd'}")  # parent directory created
    assert isinstance(sink, RerunSink)
    sink.close()
    assert (tmp_path / "sub" / "x.rrd").is_file()
    sink = make_sink(f"rerun:{tmp_path / 'q.rrd'}?images_every=5&image_side=100")
    assert sink.options == SinkOptions(images_every=5, image_side=100)
    sink.close()
    for bad in ["rerun:x.txt", "bogus:x.rrd", "mcap:", "", "rerun:y.rrd?every=2", "rerun:y.rrd?images_every=0",
                "mcap:y.mcap?image_side=big"]:
        with pytest.raises(UserError) as e:
            make_sink(bad)
        assert "\n" not in str(e.value)
    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(UserError, match="no display"):
        make_sink("rerun")
