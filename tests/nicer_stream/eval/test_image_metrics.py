"""PSNR / SSIM / depth L1: closed forms, symmetry, independent cross-check."""
from __future__ import annotations

import numpy as np
import pytest
from skimage.metrics import structural_similarity

from nicer_stream.eval.image import depth_l1, psnr, ssim


def smooth_image(h=48, w=64) -> np.ndarray:
    """(h, w, 3) float32 in [0.2, 0.8] with structure (so SSIM is informative)."""
    y, x = np.mgrid[0:h, 0:w] / 10.0
    base = np.stack([np.sin(x + c) * np.cos(y - c) for c in range(3)], -1)
    return (0.5 + 0.3 * base).astype(np.float32)


def test_identical_images():
    img = smooth_image()
    assert psnr(img, img) == float("inf")
    assert ssim(img, img) == pytest.approx(1.0, abs=1e-12)


def test_known_mse_gives_known_psnr():
    img = smooth_image()
    # +-0.1 checkerboard keeps values inside [0, 1]: MSE = 0.01 -> 20 dB (max 1).
    sign = np.where((np.indices(img.shape[:2]).sum(0) % 2) == 0, 1.0, -1.0)[..., None]
    assert psnr(img + 0.1 * sign, img) == pytest.approx(20.0, abs=1e-4)
    assert psnr(img + 0.01 * sign, img) == pytest.approx(40.0, abs=1e-3)
    assert psnr(2 * (img + 0.1 * sign), 2 * img, max_val=2.0) == pytest.approx(20.0, abs=1e-4)


def test_psnr_mask_selects_pixels():
    img = smooth_image()
    bad = img.copy()
    bad[:, :10] = 0.0
    mask = np.zeros(img.shape[:2], bool)
    mask[:, 10:] = True
    assert psnr(bad, img, mask=mask) == float("inf")
    assert np.isfinite(psnr(bad, img))


def test_ssim_symmetric_below_one_for_noise_and_matches_skimage():
    rng = np.random.default_rng(3)
    img = smooth_image()
    noisy = np.clip(img + rng.normal(size=img.shape) * 0.05, 0, 1).astype(np.float32)
    s = ssim(noisy, img)
    assert s == pytest.approx(ssim(img, noisy), abs=1e-12)
    assert 0 < s < 0.99
    ref = structural_similarity(
        noisy, img, data_range=1.0, channel_axis=-1, gaussian_weights=True, sigma=1.5, use_sample_covariance=False
    )
    assert s == pytest.approx(ref, abs=1e-6)
    # More noise, lower SSIM.
    noisier = np.clip(img + rng.normal(size=img.shape) * 0.2, 0, 1)
    assert ssim(noisier, img) < s


def test_depth_l1_scale_and_validity():
    rng = np.random.default_rng(4)
    gt = rng.uniform(0.5, 4.0, size=(20, 30)).astype(np.float32)
    gt[:5] = 0.0  # invalid GT rows must be ignored
    pred = gt / 2.5 + np.where(gt > 0, 0.0, 100.0)  # estimate in other units; garbage where GT is invalid
    assert depth_l1(pred, gt, scale=2.5) == pytest.approx(0.0, abs=1e-6)
    assert depth_l1(pred + 0.1, gt, scale=2.5) == pytest.approx(0.25, rel=1e-5)
    mask = np.zeros_like(gt, bool)
    assert depth_l1(pred, gt, mask=mask) is None
    assert depth_l1(pred, np.zeros_like(gt)) is None


def test_shape_mismatch_raises():
    a = np.zeros((20, 20, 3))
    with pytest.raises(ValueError):
        psnr(a, np.zeros((20, 21, 3)))
    with pytest.raises(ValueError):
        ssim(a, np.zeros((20, 21, 3)))
