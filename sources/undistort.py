"""Lens distortion and its removal, shared by every source that knows its lens (MCAP, video, TUM).

A `CameraCalibration` is a pinhole K plus distortion coefficients; an `Undistorter` turns its
images into images of a new pinhole camera of the same size chosen so that every output pixel
was seen by the lens (no invalid border to enter the losses), and reports that camera's K.
Models: `plumb_bob` / `rational_polynomial` (OpenCV radial-tangential, any number of
coefficients cv2 accepts) and `equidistant` (Kannala-Brandt, via `cv2.fisheye`).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from nicer_stream.errors import SourceError
from nicer_stream.types import Intrinsics
from sources.intrinsics_files import PinholeParams

RADTAN_MODELS = ("plumb_bob", "rational_polynomial", "radtan", "brown_conrady", "")
FISHEYE_MODELS = ("equidistant", "fisheye", "kannala_brandt")
ZOOM_STEP = 1.002
"""Focal length factor per step when OpenCV's camera still samples outside the input (see `_zoom_inside`)."""
MAX_ZOOM_STEPS = 200


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
        """K of the distorted image of `width` x `height` (rescaled if calibrated at another size)."""
        return self.pinhole.for_image(width, height)


def pinhole(params: PinholeParams) -> CameraCalibration:
    """A calibration without distortion (intrinsics.txt, --intrinsics, undistorted datasets)."""
    return CameraCalibration(params, np.zeros(0))


def _fisheye_coeffs(D: np.ndarray) -> np.ndarray:
    """cv2.fisheye takes exactly k1..k4."""
    D4 = np.zeros(4)
    D4[: min(4, D.size)] = D[:4]
    return D4


class Undistorter:
    """Remaps distorted (H, W, C) or (H, W) images to a pinhole camera with no invalid border.

    The new camera is OpenCV's largest pinhole view inside the lens's image
    (`getOptimalNewCameraMatrix` with alpha=0, or the fisheye `balance=0`), at the same size,
    zoomed in further where OpenCV's estimate (from a sparse grid of border points) still
    samples outside the input: every output pixel samples between input pixel centres.
    Identity (images and K unchanged) for an undistorted calibration or `enabled=False`.
    Maps and K are built once per image size (from the calibration rescaled to that size).
    """

    def __init__(self, calib: CameraCalibration, enabled: bool = True) -> None:
        self.calib = calib
        self.active = enabled and calib.is_distorted
        self._cache: dict[tuple[int, int], tuple[Intrinsics, np.ndarray, np.ndarray]] = {}

    def intrinsics(self, width: int, height: int) -> Intrinsics:
        """K of the images this returns for `width` x `height` inputs."""
        if not self.active:
            return self.calib.intrinsics(width, height)
        return self._build(width, height)[0]

    def maps(self, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """(map_x, map_y), (H, W) float32: the input pixel each output pixel samples (cv2.remap)."""
        return self._build(width, height)[1:]

    def __call__(self, image: np.ndarray, nearest: bool = False) -> np.ndarray:
        """Undistort an image (any dtype cv2.remap takes); `nearest` for depth (no mixing across edges)."""
        if not self.active:
            return image
        h, w = image.shape[:2]
        _, mx, my = self._build(w, h)
        # The maps stay inside the input's pixel centres, so replicating the edge only absorbs
        # float rounding; a constant border would darken the rim.
        return cv2.remap(image, mx, my, cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_REPLICATE)

    def _build(self, width: int, height: int) -> tuple[Intrinsics, np.ndarray, np.ndarray]:
        if (width, height) not in self._cache:
            K = self.calib.intrinsics(width, height).matrix()
            fisheye = self.calib.model in FISHEYE_MODELS
            D = _fisheye_coeffs(self.calib.distortion) if fisheye else self.calib.distortion
            if fisheye:
                new_K = cv2.fisheye.estimateNewCameraMatrixForUndistortRectify(K, D, (width, height), np.eye(3), balance=0.0)
            else:
                new_K, _ = cv2.getOptimalNewCameraMatrix(K, D, (width, height), 0.0)
            new_K, mx, my = _zoom_inside(K, D, fisheye, new_K, width, height)
            intr = Intrinsics(float(new_K[0, 0]), float(new_K[1, 1]), float(new_K[0, 2]), float(new_K[1, 2]), width, height)
            self._cache[(width, height)] = (intr, mx, my)
        return self._cache[(width, height)]


def _zoom_inside(K, D, fisheye: bool, new_K: np.ndarray, width: int, height: int):
    """(new K, map_x, map_y) with `new_K`'s focal lengths raised until every map entry lies in
    [0, W-1] x [0, H-1], the hull of the input's pixel centres."""
    new_K = new_K.copy()
    for _ in range(MAX_ZOOM_STEPS):
        if fisheye:
            mx, my = cv2.fisheye.initUndistortRectifyMap(K, D, np.eye(3), new_K, (width, height), cv2.CV_32FC1)
        else:
            mx, my = cv2.initUndistortRectifyMap(K, D, None, new_K, (width, height), cv2.CV_32FC1)
        if mx.min() >= 0 and my.min() >= 0 and mx.max() <= width - 1 and my.max() <= height - 1:
            return new_K, mx, my
        new_K[0, 0] *= ZOOM_STEP
        new_K[1, 1] *= ZOOM_STEP
    raise SourceError(f"the lens distortion {np.round(D, 4).tolist()} leaves no pinhole view inside the "
                      f"{width}x{height} image: check the calibration or pass --intrinsics fx,fy,cx,cy for undistorted images")
