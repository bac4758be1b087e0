"""Image metrics: PSNR, SSIM, depth L1.

Images are numpy (H, W, 3) (or (H, W)) float in [0, 1]; depth maps are (H, W)
float z-depth in metres with 0 = invalid (conventions.md).
"""
from __future__ import annotations

import cv2
import numpy as np

# SSIM constants of Wang et al. 2004: gaussian window 11x11, sigma 1.5.
SSIM_WIN = 11
SSIM_SIGMA = 1.5
SSIM_K1 = 0.01
SSIM_K2 = 0.03


def psnr(pred: np.ndarray, gt: np.ndarray, mask: np.ndarray | None = None, max_val: float = 1.0) -> float:
    """Peak signal-to-noise ratio in dB over all channels (inf for identical images).

    pred, gt: (H, W[, C]) arrays of the same shape; mask: optional (H, W) bool of pixels to use.
    """
    pred, gt = np.asarray(pred, np.float64), np.asarray(gt, np.float64)
    if pred.shape != gt.shape:
        raise ValueError(f"psnr: shapes differ {pred.shape} vs {gt.shape}")
    diff2 = (pred - gt) ** 2
    if mask is not None:
        diff2 = diff2[np.asarray(mask, bool)]
    mse = float(diff2.mean())
    return float("inf") if mse == 0.0 else float(10.0 * np.log10(max_val**2 / mse))


def _blur(x: np.ndarray) -> np.ndarray:
    """Gaussian-window local mean of a (H, W) float64 image, 'valid' part only (border cropped)."""
    r = SSIM_WIN // 2
    out = cv2.GaussianBlur(x, (SSIM_WIN, SSIM_WIN), SSIM_SIGMA, borderType=cv2.BORDER_REFLECT)
    return out[r:-r, r:-r]


def ssim_map(pred: np.ndarray, gt: np.ndarray, data_range: float = 1.0) -> np.ndarray:
    """(H-10, W-10) SSIM map of two (H, W) single-channel images (valid window positions only)."""
    x, y = np.asarray(pred, np.float64), np.asarray(gt, np.float64)
    c1, c2 = (SSIM_K1 * data_range) ** 2, (SSIM_K2 * data_range) ** 2
    mx, my = _blur(x), _blur(y)
    # Population (biased) local (co)variances, as in the reference implementation.
    sxx = _blur(x * x) - mx * mx
    syy = _blur(y * y) - my * my
    sxy = _blur(x * y) - mx * my
    num = (2 * mx * my + c1) * (2 * sxy + c2)
    den = (mx * mx + my * my + c1) * (sxx + syy + c2)
    return num / den


def ssim(pred: np.ndarray, gt: np.ndarray, data_range: float = 1.0) -> float:
    """Mean SSIM of (H, W[, C]) images (channels averaged); needs H, W >= 11."""
    pred, gt = np.asarray(pred), np.asarray(gt)
    if pred.shape != gt.shape:
        raise ValueError(f"ssim: shapes differ {pred.shape} vs {gt.shape}")
    if min(pred.shape[:2]) < SSIM_WIN:
        raise ValueError(f"ssim needs images of at least {SSIM_WIN}x{SSIM_WIN} pixels, got {pred.shape[:2]}")
    if pred.ndim == 2:
        return float(ssim_map(pred, gt, data_range).mean())
    return float(np.mean([ssim_map(pred[..., c], gt[..., c], data_range).mean() for c in range(pred.shape[2])]))


def depth_l1(pred: np.ndarray, gt: np.ndarray, scale: float = 1.0, mask: np.ndarray | None = None) -> float | None:
    """Mean |scale * pred - gt| in metres over pixels where gt > 0 (and `mask`, and pred finite).

    pred, gt: (H, W) z-depth; `scale` maps the estimate's units to metres (Sim(3) scale).
    Returns None when no pixel qualifies.
    """
    pred, gt = np.asarray(pred, np.float64), np.asarray(gt, np.float64)
    if pred.shape != gt.shape:
        raise ValueError(f"depth_l1: shapes differ {pred.shape} vs {gt.shape}")
    valid = (gt > 0) & np.isfinite(gt) & np.isfinite(pred)
    if mask is not None:
        valid &= np.asarray(mask, bool)
    if not valid.any():
        return None
    return float(np.abs(scale * pred[valid] - gt[valid]).mean())
