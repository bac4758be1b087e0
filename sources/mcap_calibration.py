"""Camera calibration (K + lens distortion) from MCAP messages, and undistortion maps.

Handles `foxglove.CameraCalibration` (fields `K, D, distortion_model`, upper case)
and ROS 2 `sensor_msgs/msg/CameraInfo` (fields `k, d, distortion_model`, lower case).
Distortion models: `plumb_bob` / `rational_polynomial` (OpenCV radial-tangential,
any number of coefficients cv2 accepts) and `equidistant` (Kannala-Brandt, via
`cv2.fisheye`). Undistortion keeps the same K, so the output is a pinhole image with
the calibration's intrinsics (no rectification R, P is not used).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from nicer_stream.errors import SourceError
from nicer_stream.types import Intrinsics
from sources.intrinsics_files import PinholeParams

CALIBRATION_SCHEMAS = ("foxglove.CameraCalibration", "sensor_msgs/msg/CameraInfo")
RADTAN_MODELS = ("plumb_bob", "rational_polynomial", "radtan", "brown_conrady", "")
FISHEYE_MODELS = ("equidistant", "fisheye", "kannala_brandt")


@dataclass(frozen=True)
class CameraCalibration:
    """Pinhole K plus lens distortion.

    pinhole: fx, fy, cx, cy in pixels at `pinhole.width x pinhole.height` (None: any size).
    distortion: (N,) float64 coefficients in normalised coordinates, so they do not
        change when the image is resized; all zero (or empty) means no distortion.
    model: a name from RADTAN_MODELS or FISHEYE_MODELS.
    """

    pinhole: PinholeParams
    distortion: np.ndarray
    model: str = "plumb_bob"
    frame_id: str = ""

    @property
    def is_distorted(self) -> bool:
        return bool(np.any(self.distortion != 0))

    def intrinsics(self, width: int, height: int) -> Intrinsics:
        """Intrinsics for an image of `width` x `height` (rescaled if calibrated at another size)."""
        return self.pinhole.for_image(width, height)


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


class Undistorter:
    """Remaps distorted (H, W, C) images to pinhole images with the same K.

    Maps are built once per image size (from the calibration rescaled to that size).
    """

    def __init__(self, calib: CameraCalibration) -> None:
        self.calib = calib
        self._maps: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}

    def maps(self, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """(map1, map2) for cv2.remap at this size: for each output pixel, where to sample."""
        if (width, height) not in self._maps:
            K = self.calib.intrinsics(width, height).matrix()
            D = self.calib.distortion
            if self.calib.model in FISHEYE_MODELS:
                # cv2.fisheye takes exactly k1..k4.
                D4 = np.zeros(4)
                D4[: min(4, D.size)] = D[:4]
                m1, m2 = cv2.fisheye.initUndistortRectifyMap(K, D4, np.eye(3), K, (width, height), cv2.CV_32FC1)
            else:
                m1, m2 = cv2.initUndistortRectifyMap(K, D, None, K, (width, height), cv2.CV_32FC1)
            self._maps[(width, height)] = (m1, m2)
        return self._maps[(width, height)]

    def __call__(self, image: np.ndarray) -> np.ndarray:
        """Undistort an (H, W, C) image (any dtype cv2.remap takes); pixels seen by no input are 0."""
        h, w = image.shape[:2]
        m1, m2 = self.maps(w, h)
        return cv2.remap(image, m1, m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)


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
