"""mcap: real Replica frames written as Foxglove / ROS 2 MCAP read back exactly; topic choice,
calibration pairing, undistortion, truncated and corrupt files, one-line errors."""
from __future__ import annotations

import logging

import cv2
import numpy as np
import pytest

from nicer_stream.errors import SourceError
from nicer_stream.types import Intrinsics
from sources import open_source
from sources.base import SourceOptions
from sources.mcap_calibration import calibration_from_values, pair_calibration_topic
from sources.mcap_images import CorruptImage, decode_raw
from sources.undistort import Undistorter
from tests.sources.lens_fixtures import K_TEST, LENSES, blob, centroid, distorted_pixel, pinhole_pixel
from tests.sources.mcap_fixtures import foxglove_mcap, replica_frames, ros2_mcap, stamps


@pytest.fixture(scope="module")
def clip(replica_dir):
    """(five 320x181 uint8 RGB Replica frames, their intrinsics)."""
    return replica_frames(replica_dir, n=5)


def one_line_error(uri: str, opts: SourceOptions | None = None) -> str:
    with pytest.raises(SourceError) as e:
        list(open_source(uri, opts))
    msg = str(e.value)
    assert "\n" not in msg
    return msg


CASES = {  # name -> (writer, kwargs, topic picked, tolerance kind)
    "foxglove_jpeg": (foxglove_mcap, dict(kind="jpeg"), "/cam/image", "jpeg"),
    "foxglove_raw_padded": (foxglove_mcap, dict(kind="raw", pad=7), "/cam/image", "exact"),
    "foxglove_png_no_index": (foxglove_mcap, dict(kind="png", indexed=False), "/cam/image", "exact"),
    "ros2_bgr8_with_depth_topic": (ros2_mcap, dict(kind="bgr8", depth=True), "/cam/image_raw", "exact"),
    "ros2_compressed_png": (ros2_mcap, dict(kind="png"), "/cam/image_raw/compressed", "exact"),
}


@pytest.mark.parametrize("case", CASES)
def test_frames_stamps_and_intrinsics_round_trip(case, clip, tmp_path):
    frames, intr = clip
    writer, kw, topic, tol = CASES[case]
    src = open_source(f"mcap:{writer(tmp_path / 'x.mcap', frames, intr, **kw)}")
    assert src.topic == topic
    out = list(src)
    assert [f.index for f in out] == list(range(5))
    assert [f.timestamp_ns for f in out] == stamps(5)  # sensor stamps, not log times, ns-exact
    assert np.allclose([f.timestamp for f in out], np.array(stamps(5)) * 1e-9, rtol=0, atol=1e-6)
    for f, ref in zip(out, frames):
        assert f.rgb.dtype == np.float32 and f.rgb.shape == ref.shape
        err = np.abs(f.rgb - ref / 255.0)
        if tol == "exact":
            assert err.max() <= 1 / 255 + 1e-6
        else:
            assert err.mean() < 0.03
        assert f.intrinsics == intr


def test_selection_and_resize(clip, tmp_path):
    frames, intr = clip
    path = foxglove_mcap(tmp_path / "x.mcap", frames, intr, kind="raw")
    out = list(open_source(f"mcap:{path}", SourceOptions(start=1, stride=2, max_side=160)))
    assert [f.index for f in out] == [0, 1] and [f.timestamp_ns for f in out] == [stamps(5)[1], stamps(5)[3]]
    assert out[0].width == 160 and out[0].intrinsics == intr.resized(160, out[0].height)
    ref = cv2.resize(frames[3], (160, out[1].height), interpolation=cv2.INTER_AREA) / 255.0
    assert np.abs(out[1].rgb - ref).mean() < 0.01
    assert len(list(open_source(f"mcap:{path}", SourceOptions(max_frames=2)))) == 2


def test_intrinsics_flag_replaces_missing_calibration(clip, tmp_path):
    frames, _ = clip
    path = ros2_mcap(tmp_path / "x.mcap", frames, None)
    msg = one_line_error(f"mcap:{path}")
    assert "/cam/image_raw" in msg and "--intrinsics fx,fy,cx,cy" in msg
    f = next(iter(open_source(f"mcap:{path}", SourceOptions(intrinsics=(200.0, 210.0, 150.0, 90.0)))))
    assert f.intrinsics == Intrinsics(200.0, 210.0, 150.0, 90.0, 320, 181)
    assert "positive" in one_line_error(f"mcap:{path}", SourceOptions(intrinsics=(-200.0, 210.0, 150.0, 90.0)))


def test_real_rosbag_without_images_lists_topics(data_dir):
    msg = one_line_error(f"mcap:{data_dir / 'mcap' / 'rosbag2_talker.mcap'}")
    assert msg.startswith("no image topic in")
    assert "/topic (std_msgs/msg/String)" in msg and "/rosout (rcl_interfaces/msg/Log)" in msg


def test_several_image_topics_need_topic_query(clip, tmp_path):
    frames, intr = clip
    path = foxglove_mcap(tmp_path / "x.mcap", frames[:2], intr, kind="png", topics=("/left/image", "/right/image"))
    msg = one_line_error(f"mcap:{path}")
    assert "/left/image" in msg and "/right/image" in msg and "?topic=" in msg
    src = open_source(f"mcap:{path}?topic=/right/image")
    assert src.topic == "/right/image" and len(list(src)) == 2  # single calibration topic shared
    msg = one_line_error(f"mcap:{path}?topic=/middle/image")
    assert "/middle/image" in msg and "/left/image" in msg and "/right/image" in msg


def test_depth_topic_is_not_a_camera(clip, tmp_path):
    frames, intr = clip
    path = ros2_mcap(tmp_path / "x.mcap", frames[:2], intr, depth=True)
    msg = one_line_error(f"mcap:{path}?topic=/cam/depth/image_raw")
    assert "depth" in msg and "/cam/image_raw" in msg


def test_missing_and_non_mcap_paths(tmp_path):
    assert "not found" in one_line_error(f"mcap:{tmp_path / 'nope.mcap'}")
    (tmp_path / "notes.mcap").write_text("hello")
    assert "not an MCAP file" in one_line_error(f"mcap:{tmp_path / 'notes.mcap'}")


def test_truncated_file_yields_readable_frames_and_warns(clip, tmp_path, caplog):
    frames, intr = clip
    full = ros2_mcap(tmp_path / "full.mcap", frames, intr, kind="bgr8", chunk_size=1).read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(full[: int(0.6 * len(full))])
    with caplog.at_level(logging.WARNING):
        out = list(open_source(f"mcap:{cut}"))
    assert 1 <= len(out) < 5
    assert [f.timestamp_ns for f in out] == stamps(len(out))
    for f, ref in zip(out, frames):
        assert np.abs(f.rgb - ref / 255.0).max() <= 1 / 255 + 1e-6
    assert any("truncated" in r.getMessage() and f"read {len(out)} frame" in r.getMessage() for r in caplog.records)


def test_corrupt_payload_is_skipped_and_counted(clip, tmp_path, caplog):
    frames, intr = clip
    src = open_source(f"mcap:{foxglove_mcap(tmp_path / 'x.mcap', frames, intr, kind='jpeg', corrupt=2)}")
    with caplog.at_level(logging.WARNING):
        out = list(src)
    assert src.skipped_frames == 1
    assert [f.timestamp_ns for f in out] == [s for i, s in enumerate(stamps(5)) if i != 2]
    assert [f.index for f in out] == [0, 1, 2, 3]
    assert any("skipped 1 corrupt" in r.getMessage() for r in caplog.records)


def test_mcap_camera_info_distortion_is_undone(tmp_path):
    model, D = LENSES["barrel"]
    img = (blob(160, 120, *distorted_pixel(model, D)) * 255).round().astype(np.uint8)
    f = next(iter(open_source(f"mcap:{ros2_mcap(tmp_path / 'x.mcap', [img], K_TEST, kind='rgb8', D=D)}")))
    new = Undistorter(calibration_from_values(K_TEST.matrix().reshape(-1), D, model, 160, 120)).intrinsics(160, 120)
    assert f.intrinsics == new and new != K_TEST  # the frames carry the undistorted camera
    assert np.linalg.norm(centroid(f.rgb) - pinhole_pixel(new)) < 0.5


def test_calibration_pairing_rules():
    calibs = {"/left/camera_info": "left", "/right/camera_info": "right"}
    assert pair_calibration_topic("/right/image_raw/compressed", "", calibs) == "/right/camera_info"
    assert pair_calibration_topic("/image", "left", calibs) == "/left/camera_info"  # by frame_id
    assert pair_calibration_topic("/image", "other", calibs) is None
    assert pair_calibration_topic("/anything", "", {"/calib": "x"}) == "/calib"  # the only one


def test_raw_decoding_honours_step_and_channel_order():
    rgb = np.random.default_rng(0).integers(0, 256, (3, 4, 3), dtype=np.uint8)
    bgra = np.concatenate([rgb[..., ::-1], np.full((3, 4, 1), 9, np.uint8)], axis=2).reshape(3, 16)
    padded = np.concatenate([bgra, np.full((3, 5), 200, np.uint8)], axis=1)
    out = decode_raw(padded.tobytes(), 4, 3, "bgra8", 21)
    assert np.array_equal(np.round(out * 255).astype(np.uint8), rgb)
    with pytest.raises(CorruptImage):
        decode_raw(padded.tobytes()[:-30], 4, 3, "bgra8", 21)
