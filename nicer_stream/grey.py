"""Grey copies of images, shared by the sources (the frontend's larger copy), the frontend
(corner tracking) and the stereo priors (window matching)."""
from __future__ import annotations

import cv2
import numpy as np


def to_grey_u8(rgb: np.ndarray) -> np.ndarray:
    """(H, W, 3) float RGB in [0, 1] -> (H, W) uint8 luminance; an (H, W) uint8 image is returned as it is."""
    if rgb.ndim == 2 and rgb.dtype == np.uint8:
        return rgb
    u8 = (np.clip(rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    return cv2.cvtColor(u8, cv2.COLOR_RGB2GRAY)


def to_grey_f32(rgb: np.ndarray) -> np.ndarray:
    """(H, W, 3) float RGB in [0, 1] -> (H, W) float32 luminance; an (H, W) grey image (float in
    [0, 1] or uint8) is returned as float32 in [0, 1]."""
    if rgb.ndim == 2:
        return rgb.astype(np.float32) / 255.0 if rgb.dtype == np.uint8 else rgb.astype(np.float32)
    return cv2.cvtColor(np.ascontiguousarray(rgb, dtype=np.float32), cv2.COLOR_RGB2GRAY)
