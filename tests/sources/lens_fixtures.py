"""Distorted test images whose pinhole positions are known: a Gaussian spot seen through a lens."""
from __future__ import annotations

import cv2
import numpy as np

from nicer_stream.types import Intrinsics

K_TEST = Intrinsics(100.0, 102.0, 79.5, 59.5, 160, 120)
IDEAL = np.array([132.0, 98.0])  # where a pinhole camera with K_TEST sees the point
FR1_D = [0.2624, -0.9531, -0.0054, 0.0026, 1.1633]  # TUM freiburg1, k1 k2 p1 p2 k3
LENSES = {  # name -> (model, coefficients): pincushion-like (fr1), strong barrel, fisheye
    "fr1": ("plumb_bob", FR1_D),
    "barrel": ("plumb_bob", [-0.3, 0.1, 0.002, -0.001, 0.0]),
    "fisheye": ("equidistant", [0.2, -0.05, 0.01, 0.0]),
}


def blob(width: int, height: int, u: float, v: float, sigma: float = 1.5) -> np.ndarray:
    """(H, W, 3) float32 Gaussian spot centred at pixel (u, v)."""
    vv, uu = np.mgrid[0:height, 0:width].astype(np.float64)
    g = np.exp(-((uu - u) ** 2 + (vv - v) ** 2) / (2 * sigma**2))
    return np.repeat(g[..., None], 3, axis=2).astype(np.float32)


def centroid(img: np.ndarray, r: int = 6) -> np.ndarray:
    """Sub-pixel (u, v) of the brightest spot in channel 0."""
    g = img[..., 0].astype(np.float64)
    v0, u0 = np.unravel_index(np.argmax(g), g.shape)
    win = g[v0 - r:v0 + r + 1, u0 - r:u0 + r + 1]
    vv, uu = np.mgrid[v0 - r:v0 + r + 1, u0 - r:u0 + r + 1]
    return np.array([(uu * win).sum(), (vv * win).sum()]) / win.sum()


def ideal_ray() -> np.ndarray:
    """(1, 1, 3) ray of the point IDEAL, in the camera frame (z = 1)."""
    return np.array([[[(IDEAL[0] - K_TEST.cx) / K_TEST.fx, (IDEAL[1] - K_TEST.cy) / K_TEST.fy, 1.0]]])


def distorted_pixel(model: str, D) -> np.ndarray:
    """Where the lens (K_TEST, model, D) images the point IDEAL: (2,) pixels."""
    project = cv2.fisheye.projectPoints if model == "equidistant" else cv2.projectPoints
    px, _ = project(ideal_ray(), np.zeros(3), np.zeros(3), K_TEST.matrix(), np.asarray(D, float))
    return px.reshape(2)


def pinhole_pixel(intr: Intrinsics) -> np.ndarray:
    """Where a pinhole camera `intr` sees the point IDEAL: (2,) pixels."""
    x, y, _ = ideal_ray().reshape(3)
    return np.array([intr.fx * x + intr.cx, intr.fy * y + intr.cy])
