"""Camera calibration (K + lens distortion) from MCAP messages, values and `--intrinsics`.

Handles `foxglove.CameraCalibration` (fields `K, D, distortion_model`, upper case)
and ROS 2 `sensor_msgs/msg/CameraInfo` (fields `k, d, distortion_model`, lower case).
The models and their removal are in sources.undistort (R and P are not used: the new
pinhole camera is chosen there).
"""
from __future__ import annotations

import numpy as np

from nicer_stream.errors import SourceError
from sources.intrinsics_files import PinholeParams
from sources.undistort import FISHEYE_MODELS, RADTAN_MODELS, CameraCalibration

CALIBRATION_SCHEMAS = ("foxglove.CameraCalibration", "sensor_msgs/msg/CameraInfo")


def calibration_from_values(
    k, d, model: str, width: int = 0, height: int = 0, frame_id: str = "", origin: str = ""
) -> CameraCalibration | None:
    """Build a calibration from a row-major 3x3 K (9 values), coefficients `d` and a model name.

    Returns None for an all-zero K (ROS's "uncalibrated"). Sizes <= 0 mean unknown.
    Raises SourceError for an unsupported distortion model with non-zero coefficients.
    """
    K = np.asarray(k, dtype=np.float64).reshape(-1)
    if K.size != 9 or K[0] <= 0 or K[4] <= 0:
        return None
    D = np.asarray(d if d is not None else [], dtype=np.float64).reshape(-1)
    model = (model or "").strip().lower()
    if np.any(D != 0) and model not in RADTAN_MODELS + FISHEYE_MODELS:
        raise SourceError(
            f"{origin or 'calibration'}: distortion model '{model}' is not supported "
            f"(use {', '.join(m for m in RADTAN_MODELS + FISHEYE_MODELS if m)}) or pass --intrinsics fx,fy,cx,cy for an undistorted log"
        )
    size_known = width > 0 and height > 0
    pinhole = PinholeParams(
        float(K[0]), float(K[4]), float(K[2]), float(K[5]),
        int(width) if size_known else None, int(height) if size_known else None, origin,
    )
    return CameraCalibration(pinhole, D, model or "plumb_bob", frame_id)


def calibration_from_flag(fx_fy_cx_cy: tuple[float, float, float, float]) -> CameraCalibration:
    """`--intrinsics fx,fy,cx,cy` (at the original image size) -> undistorted CameraCalibration."""
    fx, fy, cx, cy = fx_fy_cx_cy
    calib = calibration_from_values([fx, 0, cx, 0, fy, cy, 0, 0, 1], None, "plumb_bob", origin="--intrinsics")
    if calib is None:
        raise SourceError(f"--intrinsics {fx},{fy},{cx},{cy}: focal lengths fx, fy must be positive")
    return calib


def calibration_from_message(msg, schema_name: str, origin: str = "") -> CameraCalibration | None:
    """A decoded CameraCalibration / CameraInfo message -> CameraCalibration (None if uncalibrated)."""
    if schema_name == "foxglove.CameraCalibration":
        k, d, frame_id = list(msg.K), list(msg.D), msg.frame_id
    elif schema_name == "sensor_msgs/msg/CameraInfo":
        k, d, frame_id = list(msg.k), list(msg.d), msg.header.frame_id
    else:
        raise ValueError(f"not a calibration schema: {schema_name}")
    return calibration_from_values(k, d, msg.distortion_model, int(msg.width), int(msg.height), frame_id, origin)


def pair_calibration_topic(image_topic: str, image_frame_id: str, calibrations: dict[str, str]) -> str | None:
    """The calibration topic that belongs to `image_topic`, or None.

    calibrations: calibration topic -> frame_id of its first message.
    Rules, in order: the only calibration topic; the one whose namespace is the
    deepest ancestor of the image topic (`/cam/camera_info` for `/cam/image_raw`
    and `/cam/image_raw/compressed`); the only one with the image's frame_id.
    """
    if len(calibrations) == 1:
        return next(iter(calibrations))
    best, depth = [], -1
    for topic in calibrations:
        ns = topic.rsplit("/", 1)[0]
        if ns and image_topic.startswith(ns + "/"):
            d = ns.count("/")
            best, depth = ([topic], d) if d > depth else (best + [topic] if d == depth else best, depth)
    if len(best) == 1:
        return best[0]
    same_frame = [t for t, fid in calibrations.items() if image_frame_id and fid == image_frame_id]
    return same_frame[0] if len(same_frame) == 1 else None
