"""7scenes: a synthetic sequence built from real Replica frames (PNG colour, mm depth, pose.txt)."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from nicer_stream.errors import SourceError
from sources import open_source
from sources.base import SourceOptions

CROP = (slice(100, 580), slice(280, 920))  # 1200x680 -> 640x480, the 7-Scenes size


@pytest.fixture
def seven(replica_dir, tmp_path):
    """3-frame 7-Scenes folder; returns (folder, rgb uint8 list, depth mm list, poses)."""
    seq = tmp_path / "chess" / "seq-01"
    seq.mkdir(parents=True)
    traj = np.loadtxt(replica_dir / "traj.txt").reshape(-1, 4, 4)
    rgbs, depths = [], []
    for i in range(3):
        bgr = cv2.imread(str(replica_dir / "results" / f"frame{i:06d}.jpg"))[CROP]
        d = cv2.imread(str(replica_dir / "results" / f"depth{i:06d}.png"), cv2.IMREAD_UNCHANGED)[CROP]
        mm = np.round(d / 6.5535).astype(np.uint16)
        mm[:10, :10] = 65535  # invalid marker
        cv2.imwrite(str(seq / f"frame-{i:06d}.color.png"), bgr)
        cv2.imwrite(str(seq / f"frame-{i:06d}.depth.png"), mm)
        np.savetxt(seq / f"frame-{i:06d}.pose.txt", traj[i])
        rgbs.append(bgr[..., ::-1])
        depths.append(mm)
    return seq, rgbs, depths, traj[:3]


def test_frames_depth_pose_intrinsics(seven):
    seq, rgbs, depths, poses = seven
    src = open_source(f"7scenes:{seq}")
    frames = list(src)
    assert len(src) == len(frames) == 3 and src.has_gt_pose and src.name == "seq-01"
    for f, rgb, mm, T in zip(frames, rgbs, depths, poses):
        np.testing.assert_allclose(f.rgb, rgb.astype(np.float32) / 255, atol=1e-7)
        assert (f.gt_depth[:10, :10] == 0).all()
        ok = mm != 65535
        np.testing.assert_allclose(f.gt_depth[ok], mm[ok] / 1000.0, rtol=1e-6)
        np.testing.assert_allclose(f.gt_pose, T, rtol=1e-12, atol=1e-15)
    k = frames[0].intrinsics
    assert (k.fx, k.fy, k.cx, k.cy, k.width, k.height) == (585, 585, 320, 240, 640, 480)
    assert [f.timestamp for f in frames] == pytest.approx([0, 1 / 30, 2 / 30])


def test_override_selection_and_folder_detection(seven):
    seq = seven[0]
    src = open_source(f"7scenes:{seq}", SourceOptions(start=1, intrinsics=(500, 500, 319.5, 239.5)))
    frames = list(src)
    assert len(src) == 2 and frames[0].name == "frame-000001.color" and frames[0].intrinsics.fx == 500
    auto = open_source(f"folder:{seq}")
    assert len(auto) == 3 and auto.has_gt_pose and next(iter(auto)).intrinsics.fx == 585


def test_missing_pose_and_bad_pose(seven):
    seq = seven[0]
    (seq / "frame-000002.pose.txt").unlink()
    frames = list(open_source(f"7scenes:{seq}"))
    assert frames[1].gt_pose is not None and frames[2].gt_pose is None
    (seq / "frame-000000.pose.txt").write_text("1 0 0\n0 1 0\n")
    with pytest.raises(SourceError, match="4x4"):
        open_source(f"7scenes:{seq}")


def test_errors(tmp_path):
    with pytest.raises(SourceError, match="does not exist"):
        open_source(f"7scenes:{tmp_path / 'x'}")
    with pytest.raises(SourceError, match="frame-NNNNNN.color.png"):
        open_source(f"7scenes:{tmp_path}")


@pytest.fixture
def seven_jpg(tmp_path):
    """2-frame 7-Scenes folder in the `.color.jpg` layout with a camera-intrinsics.txt (3x3 K);
    returns (folder, decoded rgb uint8 list, depth mm list, poses)."""
    seq = tmp_path / "redkitchen"
    seq.mkdir()
    rng = np.random.default_rng(1)
    rgbs, depths, poses = [], [], []
    for i in range(2):
        bgr = cv2.GaussianBlur(rng.integers(0, 256, (480, 640, 3), dtype=np.uint8), (7, 7), 0)
        cv2.imwrite(str(seq / f"frame-{i:06d}.color.jpg"), bgr)
        mm = rng.integers(500, 4000, (480, 640)).astype(np.uint16)
        cv2.imwrite(str(seq / f"frame-{i:06d}.depth.png"), mm)
        T = np.eye(4)
        T[:3, 3] = [0.1 * i, -0.2, 1.5]
        np.savetxt(seq / f"frame-{i:06d}.pose.txt", T)
        rgbs.append(cv2.imread(str(seq / f"frame-{i:06d}.color.jpg"))[..., ::-1])  # as JPEG decoded
        depths.append(mm)
        poses.append(T)
    np.savetxt(seq / "camera-intrinsics.txt", [[580.0, 0, 321.0], [0, 581.0, 239.0], [0, 0, 1]])
    return seq, rgbs, depths, poses


def test_jpg_layout_with_intrinsics_matrix(seven_jpg):
    seq, rgbs, depths, poses = seven_jpg
    for uri in (f"7scenes:{seq}", f"folder:{seq}"):
        frames = list(open_source(uri))
        assert len(frames) == 2 and [f.name for f in frames] == ["frame-000000.color", "frame-000001.color"]
        for f, rgb, mm, T in zip(frames, rgbs, depths, poses):
            np.testing.assert_allclose(f.rgb, rgb.astype(np.float32) / 255, atol=1e-7)
            np.testing.assert_allclose(f.gt_depth, mm / 1000.0, rtol=1e-6)
            np.testing.assert_allclose(f.gt_pose, T)
        k = frames[0].intrinsics
        assert (k.fx, k.fy, k.cx, k.cy, k.width, k.height) == (580, 581, 321, 239, 640, 480)
    assert next(iter(open_source(f"7scenes:{seq}", SourceOptions(intrinsics=(500, 500, 320, 240))))).intrinsics.fx == 500


def test_jpg_layout_errors(seven_jpg):
    seq = seven_jpg[0]
    (seq / "camera-intrinsics.txt").write_text("585 585 320 240\n")
    with pytest.raises(SourceError, match="3x3") as e:
        open_source(f"7scenes:{seq}")
    assert "\n" not in str(e.value)
    (seq / "camera-intrinsics.txt").unlink()
    assert next(iter(open_source(f"7scenes:{seq}"))).intrinsics.fx == 585  # the dataset's default
    cv2.imwrite(str(seq / "frame-000001.color.png"), np.zeros((480, 640, 3), np.uint8))
    with pytest.raises(SourceError, match="keep one"):
        open_source(f"7scenes:{seq}")
