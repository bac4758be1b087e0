"""Write any source the project reads as a ROS 2 MCAP, the way a robot records its camera.

Topics, one message each per frame at the frame's sensor stamp:
- `/camera/image_raw/compressed` (sensor_msgs/msg/CompressedImage): the image as recorded (lens
  distortion kept), JPEG.
- `/camera/camera_info` (sensor_msgs/msg/CameraInfo): the recorded K and distortion (plumb_bob,
  or equidistant for a fisheye lens); P is the pinhole camera the `mcap:` source undistorts to.
- `/imu/data` (sensor_msgs/msg/Imu): zeros, an unrelated topic as real logs carry.
Stamps are the source's (`Frame.timestamp_ns`, else its float seconds rounded to the
microsecond: TUM lists give microseconds, and float epoch seconds hold no finer digits).
No depth and no ground truth are written: evaluate against the source folder.

Usage: .venv/bin/python scripts/to_mcap.py SRC_URI OUT.mcap [--max-frames N] [--quality Q]
e.g.   .venv/bin/python scripts/to_mcap.py tum:/work/data/rgbd_dataset_freiburg1_rpy /work/data/fr1_rpy.mcap
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np
from mcap_ros2.writer import Writer

from nicer_stream.errors import UserError
from nicer_stream.types import Frame
from sources import open_source
from sources.base import SourceOptions
from sources.intrinsics_files import PinholeParams
from sources.undistort import FISHEYE_MODELS, CameraCalibration, Undistorter, pinhole

IMAGE_TOPIC = "/camera/image_raw/compressed"
INFO_TOPIC = "/camera/camera_info"
IMU_TOPIC = "/imu/data"
FRAME_ID = "camera_optical_frame"

_SEP = "=" * 80 + "\n"
_TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
_HEADER = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
_STAMPED = _SEP + _HEADER + _SEP + _TIME
MSGDEFS = {  # ROS 2 message definitions, each followed by those it uses
    "sensor_msgs/msg/CompressedImage": "std_msgs/Header header\nstring format\nuint8[] data\n" + _STAMPED,
    "sensor_msgs/msg/CameraInfo": (
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] d\n"
        "float64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\nuint32 binning_y\n"
        "sensor_msgs/RegionOfInterest roi\n" + _STAMPED + _SEP + "MSG: sensor_msgs/RegionOfInterest\n"
        "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n"),
    "sensor_msgs/msg/Imu": (
        "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n"
        "geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n"
        "geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n" + _STAMPED
        + _SEP + "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
        + _SEP + "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"),
}


def stamp_ns(frame: Frame) -> int:
    """The frame's sensor time in integer nanoseconds (see the module docstring)."""
    if frame.timestamp_ns is not None:
        return int(frame.timestamp_ns)
    return int(round(frame.timestamp * 1e6)) * 1000


def header(ns: int) -> dict:
    return {"stamp": {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}, "frame_id": FRAME_ID}


def camera_info(calib: CameraCalibration, width: int, height: int, ns: int) -> dict:
    """CameraInfo of the recorded lens at `width` x `height`; P is the undistorted camera."""
    K = calib.intrinsics(width, height).matrix()
    P = np.hstack([Undistorter(calib).intrinsics(width, height).matrix(), np.zeros((3, 1))])
    D = [float(d) for d in calib.distortion]
    if calib.model in FISHEYE_MODELS:
        model, D = "equidistant", (D + [0.0] * 4)[:4]
    else:  # ROS's radial-tangential names: 5 coefficients, or 8 with the rational terms
        model = "plumb_bob" if len(D) <= 5 else "rational_polynomial"
        D = D + [0.0] * ((5 if len(D) <= 5 else 8) - len(D))
    return {"header": header(ns), "height": height, "width": width, "distortion_model": model, "d": D,
            "k": K.reshape(-1).tolist(), "r": np.eye(3).reshape(-1).tolist(), "p": P.reshape(-1).tolist(),
            "binning_x": 0, "binning_y": 0,
            "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0, "do_rectify": False}}


def jpeg(rgb: np.ndarray, quality: int) -> bytes:
    """(H, W, 3) float32 RGB in [0, 1] -> JPEG bytes (BGR order inside, as cv2 and ROS drivers write)."""
    bgr = cv2.cvtColor(np.round(np.clip(rgb, 0.0, 1.0) * 255.0).astype(np.uint8), cv2.COLOR_RGB2BGR)
    ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise RuntimeError("OpenCV could not encode a JPEG")
    return buf.tobytes()


def imu_zeros(ns: int) -> dict:
    zero3 = {"x": 0.0, "y": 0.0, "z": 0.0}
    return {"header": header(ns), "orientation": {**zero3, "w": 0.0}, "orientation_covariance": [0.0] * 9,
            "angular_velocity": zero3, "angular_velocity_covariance": [0.0] * 9,
            "linear_acceleration": zero3, "linear_acceleration_covariance": [0.0] * 9}


def convert(uri: str, out: Path, max_frames: int | None = None, quality: int = 95, log=print) -> int:
    """Write source `uri` to `out` (see the module docstring); returns the number of frames written."""
    src = open_source(uri, SourceOptions(max_frames=max_frames, undistort=False))
    writer = Writer(str(out))
    schemas = {name: writer.register_msgdef(name, text) for name, text in MSGDEFS.items()}
    n, t0 = 0, time.monotonic()
    try:
        for frame in src:
            ns = stamp_ns(frame)
            i = frame.intrinsics
            # A source without a lens model (synthetic, plain folders) is a pinhole camera.
            calib = src.calibration or pinhole(PinholeParams(i.fx, i.fy, i.cx, i.cy, i.width, i.height))
            writer.write_message(INFO_TOPIC, schemas["sensor_msgs/msg/CameraInfo"],
                                 camera_info(calib, frame.width, frame.height, ns), log_time=ns, publish_time=ns)
            writer.write_message(IMAGE_TOPIC, schemas["sensor_msgs/msg/CompressedImage"],
                                 {"header": header(ns), "format": "rgb8; jpeg compressed bgr8",
                                  "data": jpeg(frame.rgb, quality)}, log_time=ns, publish_time=ns)
            writer.write_message(IMU_TOPIC, schemas["sensor_msgs/msg/Imu"], imu_zeros(ns), log_time=ns, publish_time=ns)
            n += 1
            if n % 100 == 0:
                log(f"{n} frames ({time.monotonic() - t0:.0f} s)")
    finally:
        writer.finish()
    return n


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("source", help="a source URI: tum:PATH, 7scenes:PATH, folder:PATH, video:FILE, ...")
    ap.add_argument("out", type=Path, help="the .mcap file to write")
    ap.add_argument("--max-frames", type=int, default=None, help="stop after this many frames")
    ap.add_argument("--quality", type=int, default=95, help="JPEG quality, 1-100 (default 95)")
    args = ap.parse_args(argv)
    if not args.out.parent.is_dir():
        ap.error(f"the folder of {args.out} does not exist: create it or write elsewhere")
    if not 1 <= args.quality <= 100:
        ap.error(f"--quality {args.quality}: give 1-100")
    t0 = time.monotonic()
    try:
        n = convert(args.source, args.out, args.max_frames, args.quality, log=lambda m: print(m, file=sys.stderr))
    except UserError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    size = args.out.stat().st_size / 2**20
    print(f"wrote {n} frames of {args.source} to {args.out} ({size:.1f} MB, {time.monotonic() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
