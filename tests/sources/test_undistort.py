"""undistort: the new pinhole camera has no invalid border, its maps agree with OpenCV's point
undistortion, and a point seen through the lens lands where that camera projects it."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from sources.intrinsics_files import PinholeParams
from sources.mcap_calibration import calibration_from_values
from sources.undistort import Undistorter, pinhole
from tests.sources.lens_fixtures import K_TEST, LENSES, blob, centroid, distorted_pixel, pinhole_pixel

W, H = 640, 480
FR1_K = [517.3, 0, 318.6, 0, 516.5, 255.3, 0, 0, 1]


def lens(name: str, k=FR1_K, size=(W, H)) -> Undistorter:
    model, D = LENSES[name]
    return Undistorter(calibration_from_values(k, D, model, *size))


@pytest.mark.parametrize("name", LENSES)
def test_every_output_pixel_was_seen(name):
    und = lens(name)
    mx, my = und.maps(W, H)
    # Inside the hull of the input's pixel centres, so bilinear sampling needs nothing outside.
    assert mx.min() >= 0 and my.min() >= 0 and mx.max() <= W - 1 and my.max() <= H - 1
    ones = np.ones((H, W), np.float32)
    sampled = cv2.remap(ones, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    assert sampled.min() > 1 - 1e-3
    # Not cropped more than needed: the view reaches the input's edge (one axis at least: the
    # fisheye camera keeps the calibration's aspect ratio, so only one side can limit it).
    assert min(mx.min(), W - 1 - mx.max(), my.min(), H - 1 - my.max()) < 2


def test_the_calibration_k_would_leave_unseen_corners_on_fr1():
    """Why the new camera: the fr1 lens with its own K samples outside the input (the check above can fail)."""
    K, D = np.array(FR1_K, float).reshape(3, 3), np.asarray(LENSES["fr1"][1], float)
    mx, my = cv2.initUndistortRectifyMap(K, D, None, K, (W, H), cv2.CV_32FC1)
    ones = np.ones((H, W), np.float32)
    assert cv2.remap(ones, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0).min() == 0


@pytest.mark.parametrize("name", LENSES)
def test_maps_agree_with_opencv_point_undistortion(name):
    und = lens(name)
    model, D = LENSES[name]
    mx, my = und.maps(W, H)
    vv, uu = np.mgrid[0:H:16, 0:W:16]
    seen = np.stack([mx[vv, uu], my[vv, uu]], axis=-1).reshape(-1, 1, 2).astype(np.float64)
    K, P = np.array(FR1_K, float).reshape(3, 3), und.intrinsics(W, H).matrix()
    if model == "equidistant":
        back = cv2.fisheye.undistortPoints(seen, K, np.asarray(D, float), P=P)
    else:
        # OpenCV's default 5 iterations have not converged at the barrel lens's corners.
        back = cv2.undistortPoints(seen, K, np.asarray(D, float), P=P,
                                   criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12))
    err = np.linalg.norm(back.reshape(-1, 2) - np.stack([uu, vv], axis=-1).reshape(-1, 2), axis=1)
    assert err.max() < 0.1


@pytest.mark.parametrize("name", LENSES)
def test_a_point_lands_where_the_new_camera_sees_it(name):
    model, D = LENSES[name]
    seen = distorted_pixel(model, D)
    und = lens(name, K_TEST.matrix().reshape(-1), (160, 120))
    new = und.intrinsics(160, 120)
    assert np.linalg.norm(seen - pinhole_pixel(new)) > 1.0  # the point has to move
    out = und(blob(160, 120, *seen))
    assert np.linalg.norm(centroid(out) - pinhole_pixel(new)) < 0.3


def test_calibration_at_another_size_gives_the_same_camera():
    half = lens("fr1").intrinsics(W // 2, H // 2)
    full = lens("fr1").intrinsics(W, H).resized(W // 2, H // 2)
    assert abs(half.fx - full.fx) < 0.5 and abs(half.cx - full.cx) < 0.5 and abs(half.cy - full.cy) < 0.5


def test_pinhole_or_disabled_is_the_identity():
    img = np.random.default_rng(0).random((H, W, 3)).astype(np.float32)
    plain = Undistorter(pinhole(PinholeParams(500.0, 500.0, 320.0, 240.0)))
    kept = Undistorter(lens("fr1").calib, enabled=False)
    for und in (plain, kept):
        assert und(img) is img
    assert kept.intrinsics(W, H).fx == 517.3 and plain.intrinsics(W, H).cx == 320.0
