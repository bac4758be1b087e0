"""scripts/to_mcap.py: a distorted TUM fr1 folder written as a ROS 2 MCAP and read back by `mcap:`
gives the folder's frames: count, stamps, the undistorted camera, the images up to JPEG error."""
from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from nicer_stream.cli.inspect_cmd import describe_with_data
from sources import open_source
from sources.intrinsics_files import TUM_DISTORTION, TUM_PUBLISHED

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "to_mcap.py"
STAMPS = ["1305031102.175304", "1305031102.211214", "1305031102.243211"]  # TUM's microsecond stamps


@pytest.fixture(scope="module")
def to_mcap():
    spec = importlib.util.spec_from_file_location("to_mcap", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def fr1_folder(tmp_path):
    """Three smooth 640x480 frames (JPEG-friendly) in a folder named as a freiburg1 sequence."""
    seq = tmp_path / "rgbd_dataset_freiburg1_synthetic"
    (seq / "rgb").mkdir(parents=True)
    vv, uu = np.mgrid[0:480, 0:640].astype(np.float32)
    lines = []
    for i, t in enumerate(STAMPS):
        img = np.stack([128 + 100 * np.sin(uu / (40 + 10 * i)), 128 + 100 * np.cos(vv / 30),
                        128 + 100 * np.sin((uu + vv + 50 * i) / 50)], axis=-1)
        cv2.imwrite(str(seq / "rgb" / f"{t}.png"), img.astype(np.uint8))
        lines.append(f"{t} rgb/{t}.png")
    (seq / "rgb.txt").write_text("# color images\n" + "\n".join(lines) + "\n")
    return seq


def test_folder_round_trips_through_a_robot_style_mcap(to_mcap, fr1_folder, tmp_path):
    out = tmp_path / "fr1.mcap"
    assert to_mcap.convert(f"tum:{fr1_folder}", out) == 3
    folder = list(open_source(f"tum:{fr1_folder}"))
    logged = list(open_source(f"mcap:{out}"))
    assert len(logged) == len(folder) == 3
    assert [f.timestamp_ns for f in logged] == [int(t.replace(".", "")) * 1000 for t in STAMPS]
    for a, b in zip(logged, folder):
        assert abs(a.timestamp - b.timestamp) < 1e-6
        ka, kb = a.intrinsics, b.intrinsics
        assert (ka.width, ka.height) == (kb.width, kb.height)
        assert np.allclose([ka.fx, ka.fy, ka.cx, ka.cy], [kb.fx, kb.fy, kb.cx, kb.cy], rtol=0, atol=1e-6)
        assert kb.fx != TUM_PUBLISHED[1].fx  # both undistorted, not the published pinhole
        err = np.abs(a.rgb - b.rgb)
        assert err.mean() < 0.005 and np.percentile(err, 99) < 0.02  # JPEG at quality 95


def test_log_carries_the_recorded_lens_and_an_imu_topic(to_mcap, fr1_folder, tmp_path):
    out = tmp_path / "fr1.mcap"
    assert to_mcap.convert(f"tum:{fr1_folder}", out, max_frames=2) == 2
    with out.open("rb") as f:
        messages = list(make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages())
    topics = [c.topic for _, c, _, _ in messages]
    assert {t: topics.count(t) for t in topics} == {to_mcap.IMAGE_TOPIC: 2, to_mcap.INFO_TOPIC: 2, to_mcap.IMU_TOPIC: 2}
    info = next(m for _, c, _, m in messages if c.topic == to_mcap.INFO_TOPIC)
    p = TUM_PUBLISHED[1]
    assert info.distortion_model == "plumb_bob" and list(info.d) == list(TUM_DISTORTION[1])
    assert list(info.k) == [p.fx, 0, p.cx, 0, p.fy, p.cy, 0, 0, 1] and (info.width, info.height) == (640, 480)
    image = next(m for _, c, _, m in messages if c.topic == to_mcap.IMAGE_TOPIC)
    assert bytes(image.data[:2]) == b"\xff\xd8"  # a JPEG


def test_inspect_describes_the_log_and_its_lens(to_mcap, fr1_folder, tmp_path):
    out = tmp_path / "fr1.mcap"
    to_mcap.convert(f"tum:{fr1_folder}", out)
    listing = "\n".join(describe_with_data(str(out))[0])
    for topic, schema in ((to_mcap.IMAGE_TOPIC, "CompressedImage"), (to_mcap.INFO_TOPIC, "CameraInfo"),
                          (to_mcap.IMU_TOPIC, "Imu")):
        assert re.search(rf"{re.escape(topic)}\s+3 msgs\s+sensor_msgs/msg/{schema}", listing)
    source = describe_with_data(f"mcap:{out}")[0]
    assert any(line.startswith("lens: plumb_bob distortion [0.2624, -0.9531") for line in source)
