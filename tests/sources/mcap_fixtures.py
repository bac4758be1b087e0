"""Build test MCAP files and an MP4 from the first real Replica frames.

Frames are the Replica JPEGs resized to 320 px wide (uint8 RGB); what a reader
returns is compared against these arrays. Sensor stamps are odd nanosecond values
(not representable as float seconds) and log times differ from them on purpose.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from mcap.writer import CompressionType, IndexType
from mcap.writer import Writer as McapWriter
from mcap_protobuf.schema import register_schema
from mcap_ros2.writer import Writer as Ros2Writer

from nicer_stream.types import Intrinsics

WIDTH = 320
REPLICA_INTR = Intrinsics(600.0, 600.0, 599.5, 339.5, 1200, 680)
STAMP0_NS = 1_700_000_000_123_456_789
PERIOD_NS = 33_333_337
LOG_DELAY_NS = 5_000_001  # log_time = stamp + delay: a reader using log_time is caught


def replica_frames(replica_dir: Path, n: int = 5, width: int = WIDTH) -> tuple[list[np.ndarray], Intrinsics]:
    """First `n` Replica frames as (H, W, 3) uint8 RGB resized to `width`, and their intrinsics."""
    frames = []
    for i in range(n):
        bgr = cv2.imread(str(replica_dir / "results" / f"frame{i:06d}.jpg"), cv2.IMREAD_COLOR)
        h = round(bgr.shape[0] * width / bgr.shape[1])
        frames.append(cv2.cvtColor(cv2.resize(bgr, (width, h), interpolation=cv2.INTER_AREA), cv2.COLOR_BGR2RGB))
    return frames, REPLICA_INTR.resized(width, frames[0].shape[0])


def stamps(n: int) -> list[int]:
    return [STAMP0_NS + i * PERIOD_NS for i in range(n)]


def k9(intr: Intrinsics) -> list[float]:
    return [float(v) for v in intr.matrix().reshape(-1)]


# ---------------------------------------------------------------- Foxglove protobuf

def foxglove_mcap(path: Path, frames, intr: Intrinsics | None, *, kind: str = "jpeg", pad: int = 0,
                  topics=("/cam/image",), corrupt: int | None = None, indexed: bool = True, chunk_size: int = 1 << 20) -> Path:
    """Foxglove MCAP: CompressedImage (`kind` jpeg/png) or RawImage rgb8 (`kind` raw, rows padded by `pad`
    bytes) on each of `topics`, plus CameraCalibration on /cam/calibration if `intr`.
    `corrupt`: frame index whose payload is replaced by garbage. `indexed=False`: no summary, no index."""
    kw = {} if indexed else dict(index_types=IndexType.NONE, use_summary_offsets=False, use_statistics=False,
                                 repeat_channels=False, repeat_schemas=False, use_chunking=False)
    with path.open("wb") as f:
        w = McapWriter(f, chunk_size=chunk_size, compression=CompressionType.NONE, **kw)
        w.start(profile="", library="nicer-stream tests")
        channels: dict[str, int] = {}

        def write(topic, msg, t):
            if topic not in channels:
                channels[topic] = w.register_channel(topic, "protobuf", register_schema(w, type(msg)))
            w.add_message(channels[topic], log_time=t + LOG_DELAY_NS, data=msg.SerializeToString(), publish_time=t)

        for i, (rgb, t) in enumerate(zip(frames, stamps(len(frames)))):
            h, wd = rgb.shape[:2]
            if intr is not None:
                c = CameraCalibration(frame_id="cam", width=wd, height=h, distortion_model="plumb_bob",
                                      D=[0.0] * 5, K=k9(intr), R=[1, 0, 0, 0, 1, 0, 0, 0, 1], P=k9(intr)[:3] + [0] + k9(intr)[3:6] + [0, 0, 0, 1, 0])
                c.timestamp.FromNanoseconds(t)
                write("/cam/calibration", c, t)
            for topic in topics:
                msg = _foxglove_image(rgb, kind, pad)
                msg.timestamp.FromNanoseconds(t)
                if i == corrupt:
                    msg.data = b"\xff\xd8 not really a jpeg"
                write(topic, msg, t)
        w.finish()
    return path


def _foxglove_image(rgb: np.ndarray, kind: str, pad: int):
    h, wd = rgb.shape[:2]
    if kind == "raw":
        rows = np.zeros((h, wd * 3 + pad), np.uint8)
        rows[:, : wd * 3] = rgb.reshape(h, -1)
        rows[:, wd * 3:] = 77  # padding bytes must be ignored
        return RawImage(frame_id="cam", width=wd, height=h, encoding="rgb8", step=wd * 3 + pad, data=rows.tobytes())
    params = [cv2.IMWRITE_JPEG_QUALITY, 95] if kind == "jpeg" else []
    ok, buf = cv2.imencode("." + kind, cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), params)
    return CompressedImage(frame_id="cam", format=kind, data=buf.tobytes())


# ---------------------------------------------------------------- ROS 2

_TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
_HEADER = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
_SEP = "=" * 80 + "\n"
ROS_IMAGE = ("std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\n"
             "uint32 step\nuint8[] data\n" + _SEP + _HEADER + _SEP + _TIME)
ROS_COMPRESSED = "std_msgs/Header header\nstring format\nuint8[] data\n" + _SEP + _HEADER + _SEP + _TIME
ROS_CAMERA_INFO = (
    "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] d\n"
    "float64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\nuint32 binning_y\n"
    "sensor_msgs/RegionOfInterest roi\n" + _SEP + _HEADER + _SEP + _TIME + _SEP
    + "MSG: sensor_msgs/RegionOfInterest\nuint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n"
)


def _header(t: int, frame: str = "cam_optical") -> dict:
    return {"stamp": {"sec": t // 1_000_000_000, "nanosec": t % 1_000_000_000}, "frame_id": frame}


def ros2_mcap(path: Path, frames, intr: Intrinsics | None, *, kind: str = "bgr8", ns: str = "/cam",
              D=None, model: str = "plumb_bob", depth: bool = False, chunk_size: int = 1 << 20) -> Path:
    """ROS 2 MCAP: `{ns}/image_raw` sensor_msgs/Image (`kind` bgr8/rgb8/mono8...) or
    `{ns}/image_raw/compressed` CompressedImage (`kind` png/jpeg), `{ns}/camera_info` if `intr`,
    a 16UC1 `{ns}/depth/image_raw` if `depth`. Small `chunk_size` puts each message in its own chunk."""
    w = Ros2Writer(str(path), chunk_size=chunk_size, compression=CompressionType.NONE)
    s_img, s_cmp = w.register_msgdef("sensor_msgs/msg/Image", ROS_IMAGE), w.register_msgdef("sensor_msgs/msg/CompressedImage", ROS_COMPRESSED)
    s_info = w.register_msgdef("sensor_msgs/msg/CameraInfo", ROS_CAMERA_INFO)
    for rgb, t in zip(frames, stamps(len(frames))):
        h, wd = rgb.shape[:2]
        if intr is not None:
            info = {"header": _header(t), "height": h, "width": wd, "distortion_model": model,
                    "d": list(D) if D is not None else [0.0] * 5, "k": k9(intr), "r": [1.0, 0, 0, 0, 1, 0, 0, 0, 1],
                    "p": [0.0] * 12, "binning_x": 0, "binning_y": 0,
                    "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0, "do_rectify": False}}
            w.write_message(f"{ns}/camera_info", s_info, info, log_time=t + LOG_DELAY_NS)
        if kind in ("png", "jpeg"):
            ok, buf = cv2.imencode("." + kind, cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
            msg = {"header": _header(t), "format": f"rgb8; {kind} compressed bgr8", "data": buf.tobytes()}
            w.write_message(f"{ns}/image_raw/compressed", s_cmp, msg, log_time=t + LOG_DELAY_NS)
        else:
            data = {"bgr8": lambda x: x[..., ::-1], "rgb8": lambda x: x,
                    "mono8": lambda x: x[..., :1]}[kind](rgb)
            msg = {"header": _header(t), "height": h, "width": wd, "encoding": kind, "is_bigendian": 0,
                   "step": wd * data.shape[2], "data": np.ascontiguousarray(data).tobytes()}
            w.write_message(f"{ns}/image_raw", s_img, msg, log_time=t + LOG_DELAY_NS)
        if depth:
            d = np.full((h, wd), 1500, np.uint16)
            msg = {"header": _header(t), "height": h, "width": wd, "encoding": "16UC1", "is_bigendian": 0,
                   "step": wd * 2, "data": d.tobytes()}
            w.write_message(f"{ns}/depth/image_raw", s_img, msg, log_time=t + LOG_DELAY_NS)
    w.finish()
    return path


def write_mp4(path: Path, frames, fps: float) -> Path:
    """MP4 (mp4v) of uint8 RGB frames at `fps`; mp4v needs an even width and height."""
    h, wd = frames[0].shape[:2]
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (wd, h))
    assert vw.isOpened(), "OpenCV cannot write mp4v here"
    for rgb in frames:
        vw.write(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    vw.release()
    return path
