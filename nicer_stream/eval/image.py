"""Image metrics: PSNR, SSIM, depth L1.

Images are numpy (H, W, 3) (or (H, W)) float in [0, 1]; depth maps are (H, W)
float z-depth in metres with 0 = invalid (conventions.md).
"""
from __future__ import annotations

import numpy as np
from skimage.metrics import structural_similarity

SSIM_WIN = 11  # skimage's window for sigma 1.5 (truncated at 3.5 sigma)


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


def ssim(pred: np.ndarray, gt: np.ndarray, data_range: float = 1.0) -> float:
    """Mean SSIM of (H, W[, C]) images (channels averaged); needs H, W >= 11. Wang et al. 2004's
    constants (gaussian window 11x11, sigma 1.5, population (co)variances), computed in float64."""
    pred, gt = np.asarray(pred, np.float64), np.asarray(gt, np.float64)
    if pred.shape != gt.shape:
        raise ValueError(f"ssim: shapes differ {pred.shape} vs {gt.shape}")
    if min(pred.shape[:2]) < SSIM_WIN:
        raise ValueError(f"ssim needs images of at least {SSIM_WIN}x{SSIM_WIN} pixels, got {pred.shape[:2]}")
    channels = -1 if pred.ndim == 3 else None
    return float(structural_similarity(pred, gt, data_range=data_range, channel_axis=channels,
                                       gaussian_weights=True, sigma=1.5, use_sample_covariance=False))


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
