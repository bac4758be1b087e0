"""tum: real fr3 clip, timestamp association, intrinsics precedence, depth.txt."""
from __future__ import annotations

import shutil

import cv2
import numpy as np
import pytest

from nicer_stream.errors import SourceError
from sources import open_source
from nicer_stream.grey import to_grey_u8
from sources.base import SourceOptions, read_rgb
from sources.intrinsics_files import TUM_DISTORTION, TUM_PUBLISHED, tum_camera
from sources.tum import associate
from sources.undistort import CameraCalibration, Undistorter


def gt_rows(tum_dir):
    rows = [l.split() for l in (tum_dir / "groundtruth.txt").read_text().splitlines() if l and not l.startswith("#")]
    return np.array(rows, dtype=np.float64)


def quat_xyzw(R):
    """Rotation -> (x, y, z, w) with w >= 0 (independent of se3.py, via the trace formula)."""
    w = np.sqrt(max(0.0, 1 + np.trace(R))) / 2
    q = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / (4 * w)
    return np.append(q, w)


def test_clip_frames_intrinsics_timestamps(tum_dir):
    src = open_source(f"tum:{tum_dir}")
    frames = list(src)
    assert len(src) == len(frames) == 4 and src.has_gt_pose
    t_list = [float(l.split()[0]) for l in (tum_dir / "rgb.txt").read_text().splitlines() if l and l[0] != "#"]
    assert [f.timestamp for f in frames] == t_list
    k = frames[0].intrinsics
    assert (k.fx, k.fy, k.cx, k.cy, k.width, k.height) == (535.4, 539.2, 320.1, 247.6, 640, 480)
    assert frames[0].rgb.shape == (480, 640, 3) and frames[0].gt_depth is None


def test_gt_pose_is_nearest_groundtruth_row(tum_dir):
    gt = gt_rows(tum_dir)
    for f in open_source(f"tum:{tum_dir}"):
        i = int(np.argmin(np.abs(gt[:, 0] - f.timestamp)))
        if abs(gt[i, 0] - f.timestamp) > 0.02:
            assert f.gt_pose is None  # frame 0: mocap starts 0.067 s after it
            continue
        np.testing.assert_allclose(f.gt_pose[:3, 3], gt[i, 1:4])
        q = gt[i, 4:8] / np.linalg.norm(gt[i, 4:8])
        q = q if q[3] >= 0 else -q
        np.testing.assert_allclose(quat_xyzw(f.gt_pose[:3, :3]), q, atol=1e-6)


def test_one_frame_checked_by_hand(tum_dir):
    # rgb 1341847984.106759 -> groundtruth line 1341847984.1100 (dt 3.2 ms):
    # 0.0258 2.7128 1.7191 0.0742 0.8564 -0.5058 -0.0727
    f = list(open_source(f"tum:{tum_dir}"))[1]
    np.testing.assert_allclose(f.gt_pose[:3, 3], [0.0258, 2.7128, 1.7191])
    np.testing.assert_allclose(-quat_xyzw(f.gt_pose[:3, :3]), [0.0742, 0.8564, -0.5058, -0.0727], atol=2e-4)


def test_associate_nearest_within_tolerance():
    ref = np.array([3.0, 1.0, 2.0, 10.0])  # unsorted on purpose
    q = np.array([0.99, 1.49, 1.51, 2.021, 9.999, 12.0, -5.0])
    out = associate(q, ref, max_dt=0.02)
    assert out.tolist() == [1, -1, -1, -1, 3, -1, -1]
    assert associate(q, ref, max_dt=0.6).tolist() == [1, 1, 2, 2, 3, -1, -1]
    assert associate(q, np.array([2.0]), max_dt=0.1).tolist() == [-1, -1, -1, 0, -1, -1, -1]
    assert associate(q, np.array([]), max_dt=1).tolist() == [-1] * 7


def copy_rgb(tum_dir, dst):
    dst.mkdir(parents=True)
    shutil.copytree(tum_dir / "rgb", dst / "rgb")
    shutil.copy(tum_dir / "rgb.txt", dst)
    return dst


def test_missing_intrinsics_asks_for_flag(tum_dir, tmp_path):
    seq = copy_rgb(tum_dir, tmp_path / "office")
    with pytest.raises(SourceError) as e:
        open_source(f"tum:{seq}")
    assert "--intrinsics" in str(e.value) and "\n" not in str(e.value)
    k = next(iter(open_source(f"tum:{seq}", SourceOptions(intrinsics=(500, 501, 300, 200))))).intrinsics
    assert (k.fx, k.fy, k.cx, k.cy, k.width) == (500, 501, 300, 200, 640)


def test_published_fr3_calibration_is_pinhole(tum_dir, tmp_path):
    seq = copy_rgb(tum_dir, tmp_path / "rgbd_dataset_freiburg3_xyz")
    src = open_source(f"tum:{seq}", SourceOptions(max_side=320))
    assert not src.has_gt_pose
    f = next(iter(src))
    k = f.intrinsics
    assert k.width == 320 and k.fx == pytest.approx(535.4 / 2) and k.cx == pytest.approx((320.1 + 0.5) / 2 - 0.5)
    raw = cv2.resize(read_rgb(sorted((seq / "rgb").iterdir())[0]), (320, 240), interpolation=cv2.INTER_AREA)
    assert np.array_equal(f.rgb, raw)  # fr3 images are published undistorted: unchanged
    assert tum_camera("fr2_desk") == 2 and tum_camera("tum_fr3_office") == 3
    assert tum_camera("frame10") is None and tum_camera("freiburg12") is None


@pytest.fixture
def fr1(tum_dir, tmp_path):
    """A folder named as a freiburg1 sequence: the four fr3 frames, then an all-white frame, and
    a depth image (a horizontal ramp) for the first frame."""
    seq = copy_rgb(tum_dir, tmp_path / "rgbd_dataset_freiburg1_x")
    cv2.imwrite(str(seq / "rgb" / "white.png"), np.full((480, 640, 3), 255, np.uint8))
    with (seq / "rgb.txt").open("a") as f:
        f.write("1341847999.000000 rgb/white.png\n")
    (seq / "depth").mkdir()
    ramp = np.tile(np.arange(640, dtype=np.uint16) * 50 + 1000, (480, 1))
    cv2.imwrite(str(seq / "depth" / "d0.png"), ramp)
    t0 = (seq / "rgb.txt").read_text().split("\n")
    t0 = next(line.split()[0] for line in t0 if line and line[0] != "#")
    (seq / "depth.txt").write_text(f"{t0} depth/d0.png\n")
    return seq, ramp / 5000.0


def test_fr1_frames_are_undistorted_without_border(fr1):
    seq, ramp = fr1
    lens = Undistorter(CameraCalibration(TUM_PUBLISHED[1], np.asarray(TUM_DISTORTION[1])))
    new = lens.intrinsics(640, 480)
    assert abs(new.fx - 517.3) > 10  # the undistorted camera is not the published pinhole
    src = open_source(f"tum:{seq}", SourceOptions(max_side=320, detail_side=640))
    frames = list(src)
    assert len(frames) == 5 and all(f.intrinsics == new.resized(320, 240) for f in frames)
    raw = read_rgb(sorted((seq / "rgb").glob("1*.png"))[0])
    straight = lens(raw)
    assert np.abs(straight - raw).mean() > 0.01
    assert np.array_equal(frames[0].rgb, cv2.resize(straight, (320, 240), interpolation=cv2.INTER_AREA))
    # The frontend's image is undistorted too, with the undistorted camera at its size.
    assert frames[0].detail.intrinsics == new and np.array_equal(frames[0].detail.grey, to_grey_u8(straight))
    # No pixel the lens did not see: a white input stays white everywhere.
    assert frames[-1].rgb.min() == 1.0 and frames[-1].detail.grey.min() == 255
    # GT depth follows the RGB's pixels (nearest: no mixing across depth edges).
    full = next(iter(open_source(f"tum:{seq}")))
    assert np.array_equal(full.gt_depth, lens(ramp.astype(np.float32), nearest=True))
    assert not np.allclose(full.gt_depth, ramp)


def test_fr1_raw_frames_and_user_intrinsics_are_not_undistorted(fr1, tum_dir):
    seq, _ = fr1
    raw = read_rgb(sorted((seq / "rgb").glob("1*.png"))[0])
    src = open_source(f"tum:{seq}", SourceOptions(undistort=False))
    f = next(iter(src))
    assert np.array_equal(f.rgb, raw) and f.intrinsics == TUM_PUBLISHED[1].for_image(640, 480)
    assert np.array_equal(src.calibration.distortion, TUM_DISTORTION[1])
    flag = next(iter(open_source(f"tum:{seq}", SourceOptions(intrinsics=(517.3, 516.5, 318.6, 255.3)))))
    shutil.copy(tum_dir / "intrinsics.txt", seq)
    txt = next(iter(open_source(f"tum:{seq}")))
    for pinhole in (flag, txt):  # the user's intrinsics mean a pinhole camera
        assert np.array_equal(pinhole.rgb, raw)


def test_depth_txt_associated_and_scaled(tum_dir, tmp_path):
    seq = copy_rgb(tum_dir, tmp_path / "office")
    shutil.copy(tum_dir / "intrinsics.txt", seq)
    (seq / "depth").mkdir()
    t = [float(l.split()[0]) for l in (seq / "rgb.txt").read_text().splitlines() if l and l[0] != "#"]
    depth = np.random.default_rng(0).integers(0, 40000, size=(480, 640)).astype(np.uint16)
    lines = []
    for j, ti in enumerate(t[:3]):  # frame 3 gets no depth; frame 2's is 0.03 s off: unmatched
        td = ti + (0.01 if j < 2 else 0.03)
        cv2.imwrite(str(seq / "depth" / f"{td:.6f}.png"), depth)
        lines.append(f"{td:.6f} depth/{td:.6f}.png")
    (seq / "depth.txt").write_text("# depth\n" + "\n".join(lines) + "\n")
    frames = list(open_source(f"tum:{seq}"))
    np.testing.assert_allclose(frames[0].gt_depth, depth / 5000.0, rtol=1e-6)
    assert frames[1].gt_depth is not None and frames[2].gt_depth is None and frames[3].gt_depth is None


def test_bad_paths(tmp_path):
    with pytest.raises(SourceError, match="does not exist"):
        open_source(f"tum:{tmp_path / 'missing'}")
    with pytest.raises(SourceError, match="rgb.txt"):
        open_source(f"tum:{tmp_path}")
