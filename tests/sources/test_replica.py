"""replica: real NICE-SLAM clip read correctly, resizing, selection, intrinsics lookup, corrupt frames."""
from __future__ import annotations

import itertools
import logging
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from nicer_stream.errors import SourceError
from sources import open_source
from sources.base import SourceOptions


def first(src):
    return next(iter(src))


def test_clip_size_intrinsics_and_count(replica_dir):
    src = open_source(f"replica:{replica_dir}")
    assert len(src) == 20 and src.has_gt_pose
    f = first(src)
    assert f.rgb.shape == (680, 1200, 3) and f.rgb.dtype == np.float32
    assert 0.0 <= f.rgb.min() and f.rgb.max() <= 1.0
    assert (f.intrinsics.fx, f.intrinsics.fy, f.intrinsics.width, f.intrinsics.height) == (600.0, 600.0, 1200, 680)


def test_max_side_resizes_with_pixel_centre_rule(replica_dir):
    f = first(open_source(f"replica:{replica_dir}", SourceOptions(max_side=320)))
    k = f.intrinsics
    assert f.rgb.shape == (181, 320, 3) and (k.width, k.height) == (320, 181)
    assert k.fx == pytest.approx(600 * 320 / 1200) and k.fy == pytest.approx(600 * 181 / 680)
    # cam_params' principal point is the exact image centre (W-1)/2; the pixel-centre rule keeps it
    # there (a naive cx*s would give 159.87).
    assert k.cx == pytest.approx((k.width - 1) / 2) and k.cy == pytest.approx((k.height - 1) / 2)
    assert f.gt_depth.shape == f.rgb.shape[:2]


def test_depth_is_metres_and_matches_png(replica_dir):
    f = first(open_source(f"replica:{replica_dir}"))
    raw = cv2.imread(str(replica_dir / "results" / "depth000000.png"), cv2.IMREAD_UNCHANGED)
    assert f.gt_depth.dtype == np.float32 and f.gt_depth.shape == f.rgb.shape[:2]
    np.testing.assert_allclose(f.gt_depth, raw / 6553.5, rtol=1e-6)
    valid = f.gt_depth[f.gt_depth > 0]
    assert valid.size > 0.9 * f.gt_depth.size
    assert 0.3 < valid.min() and valid.max() < 10.0


def test_gt_pose_is_traj_row(replica_dir):
    traj = np.loadtxt(replica_dir / "traj.txt").reshape(-1, 4, 4)
    f = first(open_source(f"replica:{replica_dir}"))
    assert f.gt_pose.dtype == np.float64
    np.testing.assert_array_equal(f.gt_pose, traj[0])
    np.testing.assert_allclose(f.gt_pose[:3, :3] @ f.gt_pose[:3, :3].T, np.eye(3), atol=1e-6)


def test_start_stride_max_frames(replica_dir):
    opts = SourceOptions(start=2, stride=3, max_frames=4, max_side=64)
    src = open_source(f"replica:{replica_dir}", opts)
    frames = list(src)
    raw = [2, 5, 8, 11]
    assert len(src) == len(frames) == 4
    assert [f.index for f in frames] == [0, 1, 2, 3]
    assert [f.name for f in frames] == [f"frame{i:06d}" for i in raw]
    assert [f.timestamp for f in frames] == pytest.approx([i / 30 for i in raw])
    traj = np.loadtxt(replica_dir / "traj.txt").reshape(-1, 4, 4)
    for f, i in zip(frames, raw):
        np.testing.assert_array_equal(f.gt_pose, traj[i])
    assert len(open_source(f"replica:{replica_dir}", SourceOptions(start=15, stride=2))) == 3


def test_fps_query_sets_timestamps(replica_dir):
    src = open_source(f"replica:{replica_dir}?fps=10", SourceOptions(start=5, max_frames=1, max_side=32))
    assert first(src).timestamp == pytest.approx(0.5)
    with pytest.raises(SourceError, match="fps"):
        open_source(f"replica:{replica_dir}?fsp=10")


def make_sequence(replica_dir: Path, seq: Path, n: int = 3) -> Path:
    """Copy the first n frames (RGB, depth, traj rows) of the real clip into `seq`."""
    (seq / "results").mkdir(parents=True)
    for i in range(n):
        for kind, ext in (("frame", "jpg"), ("depth", "png")):
            shutil.copy(replica_dir / "results" / f"{kind}{i:06d}.{ext}", seq / "results")
    rows = (replica_dir / "traj.txt").read_text().splitlines()[:n]
    (seq / "traj.txt").write_text("\n".join(rows) + "\n")
    return seq


def test_cam_params_found_two_levels_up(replica_dir, tmp_path):
    seq = make_sequence(replica_dir, tmp_path / "Replica" / "scenes" / "room0")
    with pytest.raises(SourceError, match="--intrinsics"):
        open_source(f"replica:{seq}")
    shutil.copy(replica_dir / "cam_params.json", tmp_path / "Replica")
    assert first(open_source(f"replica:{seq}")).intrinsics.cx == 599.5
    over = SourceOptions(intrinsics=(500.0, 510.0, 600.0, 340.0))
    k = first(open_source(f"replica:{seq}", over)).intrinsics
    assert (k.fx, k.fy, k.cx, k.cy) == (500.0, 510.0, 600.0, 340.0)


def test_missing_intrinsics_message_is_one_line(replica_dir, tmp_path):
    seq = make_sequence(replica_dir, tmp_path / "a" / "b" / "c" / "room0", n=1)
    shutil.copy(replica_dir / "cam_params.json", tmp_path / "a")  # three levels up: not searched
    with pytest.raises(SourceError) as e:
        open_source(f"replica:{seq}")
    assert "\n" not in str(e.value) and "--intrinsics fx,fy,cx,cy" in str(e.value)


def test_corrupt_frame_skipped_and_counted(replica_dir, tmp_path, caplog):
    seq = make_sequence(replica_dir, tmp_path / "room0")
    shutil.copy(replica_dir / "cam_params.json", seq)
    (seq / "results" / "frame000001.jpg").write_bytes(b"not a jpeg at all")
    src = open_source(f"replica:{seq}", SourceOptions(max_side=64))
    with caplog.at_level(logging.WARNING):
        frames = list(src)
    assert len(src) == 3 and len(frames) == 2 and src.skipped_frames == 1
    assert [f.index for f in frames] == [0, 1] and [f.name for f in frames] == ["frame000000", "frame000002"]
    assert any("frame000001.jpg" in r.getMessage() for r in caplog.records)


def test_missing_traj_means_no_gt_pose(replica_dir, tmp_path):
    seq = make_sequence(replica_dir, tmp_path / "room0", n=1)
    shutil.copy(replica_dir / "cam_params.json", seq)
    (seq / "traj.txt").unlink()
    src = open_source(f"replica:{seq}", SourceOptions(max_side=64))
    assert not src.has_gt_pose and first(src).gt_pose is None and first(src).gt_depth is not None


def test_empty_and_missing_folders(tmp_path):
    with pytest.raises(SourceError, match="does not exist"):
        open_source(f"replica:{tmp_path / 'nope'}")
    with pytest.raises(SourceError, match="results/frameNNNNNN.jpg"):
        open_source(f"replica:{tmp_path}")


def test_frames_are_read_lazily(replica_dir, tmp_path):
    seq = make_sequence(replica_dir, tmp_path / "room0", n=2)
    shutil.copy(replica_dir / "cam_params.json", seq)
    it = iter(open_source(f"replica:{seq}", SourceOptions(max_side=64)))
    list(itertools.islice(it, 1))
    (seq / "results" / "frame000001.jpg").unlink()  # removed after opening: only noticed when reached
    assert list(it) == []
