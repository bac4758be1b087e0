"""video: an MP4 of real Replica frames read back within codec error, container timestamps,
intrinsics from --intrinsics / calibration files / FOV guess, one-line errors."""
from __future__ import annotations

import json
import logging
import math

import numpy as np
import pytest

from nicer_stream.errors import SourceError
from nicer_stream.types import Intrinsics
from sources import open_source
from sources.base import SourceOptions
from sources.calibration_file import read_calibration_file
from sources.undistort import Undistorter
from sources.video import fov_intrinsics
from tests.sources.mcap_fixtures import replica_frames, write_mp4

FPS = 10.0
INTR = (170.0, 171.0, 158.0, 91.0)


@pytest.fixture(scope="module")
def clip(replica_dir, tmp_path_factory):
    """(path of a 5-frame 320x180 mp4v MP4 in its own folder, the uint8 RGB frames written)."""
    frames, _ = replica_frames(replica_dir, n=5)
    frames = [f[:180] for f in frames]  # mp4v needs even sizes
    return write_mp4(tmp_path_factory.mktemp("video") / "clip.mp4", frames, FPS), frames


def test_frames_timestamps_and_flag_intrinsics(clip, caplog):
    path, frames = clip
    with caplog.at_level(logging.WARNING):
        out = list(open_source(f"video:{path}", SourceOptions(intrinsics=INTR)))
    assert not caplog.records  # real intrinsics given: no guess warning
    assert len(out) == len(frames) and [f.index for f in out] == list(range(5))
    for f, ref in zip(out, frames):
        assert f.rgb.dtype == np.float32 and f.rgb.shape == ref.shape
        assert np.abs(f.rgb - ref / 255.0).mean() < 0.05
        assert f.intrinsics == Intrinsics(*INTR, 320, 180)
    t = np.array([f.timestamp for f in out])
    assert np.all(np.diff(t) > 0) and np.allclose(t, np.arange(5) / FPS, atol=1e-3)


def test_selection(clip):
    path, frames = clip
    out = list(open_source(f"video:{path}", SourceOptions(start=1, stride=2, intrinsics=INTR)))
    assert [f.index for f in out] == [0, 1] and np.allclose([f.timestamp for f in out], [0.1, 0.3], atol=1e-3)
    assert np.abs(out[1].rgb - frames[3] / 255.0).mean() < 0.05
    assert len(list(open_source(f"video:{path}", SourceOptions(max_frames=2, intrinsics=INTR)))) == 2


def test_fov_guess_warns_and_fov_query_overrides(clip, caplog):
    path, _ = clip
    with caplog.at_level(logging.WARNING):
        f = next(iter(open_source(f"video:{path}")))
    assert any("--intrinsics fx,fy,cx,cy" in r.getMessage() and "60 deg" in r.getMessage() for r in caplog.records)
    assert math.isclose(f.intrinsics.fx, 160.0 / math.tan(math.radians(30.0)))
    assert (f.intrinsics.cx, f.intrinsics.cy) == (159.5, 89.5)
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        f = next(iter(open_source(f"video:{path}?fov=90")))
    assert not caplog.records and math.isclose(f.intrinsics.fx, 160.0) and f.intrinsics.fy == f.intrinsics.fx


def test_fov_closed_form():
    i = fov_intrinsics(640, 480, 90.0)
    # the left image border (u = -0.5) sits exactly at 45 deg
    assert math.isclose(math.degrees(math.atan((i.cx + 0.5) / i.fx)), 45.0)


def test_sidecar_and_calib_query(clip, tmp_path):
    path, frames = clip
    side = path.with_name("intrinsics.txt")
    side.write_text("# fx fy cx cy\n150 151 160 90\n")
    try:
        f = next(iter(open_source(f"video:{path}")))
        assert f.intrinsics == Intrinsics(150.0, 151.0, 160.0, 90.0, 320, 180)
    finally:
        side.unlink()
    # A calibration given at twice the video's size is rescaled; D undistorts the frames.
    calib = tmp_path / "cam.json"
    calib.write_text(json.dumps({"K": [[340, 0, 319.5], [0, 340, 179.5], [0, 0, 1]], "D": [-0.2, 0, 0, 0],
                                 "width": 640, "height": 360}))
    f = next(iter(open_source(f"video:{path}?calib={calib}")))
    lens = read_calibration_file(calib)
    assert lens.intrinsics(320, 180) == Intrinsics(340, 340, 319.5, 179.5, 640, 360).resized(320, 180)
    assert f.intrinsics == Undistorter(lens).intrinsics(320, 180)
    plain = next(iter(open_source(f"video:{path}", SourceOptions(intrinsics=INTR))))
    assert np.abs(f.rgb - plain.rgb).mean() > 0.01  # undistortion changed the image
    assert np.abs(f.rgb[85:96, 150:170] - plain.rgb[85:96, 150:170]).mean() < 0.02  # but not the centre


def test_ros_camera_info_yaml(tmp_path):
    p = tmp_path / "cam.yaml"
    p.write_text("image_width: 640\nimage_height: 480\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
                 "  data: [500.0, 0.0, 319.5, 0.0, 501.0, 239.5, 0.0, 0.0, 1.0]\n"
                 "distortion_model: equidistant\ndistortion_coefficients:\n  rows: 1\n  cols: 4\n  data: [0.1, -0.05, 0.0, 0.0]\n")
    c = read_calibration_file(p)
    assert c.intrinsics(640, 480) == Intrinsics(500.0, 501.0, 319.5, 239.5, 640, 480)
    assert c.model == "equidistant" and np.allclose(c.distortion, [0.1, -0.05, 0, 0])


def one_line_error(uri: str) -> str:
    with pytest.raises(SourceError) as e:
        list(open_source(uri))
    assert "\n" not in str(e.value)
    return str(e.value)


def test_errors(clip, tmp_path):
    path, _ = clip
    assert "not found" in one_line_error(f"video:{tmp_path / 'missing.mp4'}")
    (tmp_path / "bad.mp4").write_bytes(b"not a video" * 100)
    assert "cannot open video" in one_line_error(f"video:{tmp_path / 'bad.mp4'}")
    assert "field of view" in one_line_error(f"video:{path}?fov=200")
    assert "not found" in one_line_error(f"video:{path}?calib={tmp_path / 'none.yaml'}")
    (tmp_path / "k.json").write_text(json.dumps({"D": [0.1]}))
    assert "camera matrix" in one_line_error(f"video:{path}?calib={tmp_path / 'k.json'}")
