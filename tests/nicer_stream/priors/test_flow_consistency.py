"""Closed-form checks of the forward/backward consistency mask."""
from __future__ import annotations

import numpy as np
import pytest

from nicer_stream.priors.flow_consistency import consistency_mask, in_image_mask, warp_backward_flow

H, W = 12, 20


def const(du: float, dv: float) -> np.ndarray:
    f = np.zeros((H, W, 2), np.float32)
    f[..., 0], f[..., 1] = du, dv
    return f


def test_translation_is_consistent_except_where_it_leaves_the_image():
    fw, bw = const(2.4, -1.6), const(-2.4, 1.6)
    mask = consistency_mask(fw, bw)
    # Kept: x + 2.4 <= W - 0.5 and y - 1.6 >= -0.5, i.e. columns 0..W-3 and rows 2..H-1.
    expected = np.zeros((H, W), bool)
    expected[2:, : W - 2] = True
    np.testing.assert_array_equal(mask, expected)
    np.testing.assert_array_equal(in_image_mask(fw), expected)


def test_backward_flow_is_sampled_at_the_forward_target():
    """A backward flow linear in x is interpolated exactly by bilinear sampling."""
    fw = const(1.25, 0.5)
    x = np.arange(W, dtype=np.float32)[None, :].repeat(H, 0)
    bw = np.stack([0.1 * x, np.zeros_like(x)], -1)
    warped = warp_backward_flow(fw, bw)
    inner = (slice(0, H - 1), slice(0, W - 2))  # away from the clamped border
    np.testing.assert_allclose(warped[inner][..., 0], 0.1 * (x[inner] + 1.25), atol=1e-3)


@pytest.mark.parametrize("alpha,beta", [(0.005, 0.1), (0.01, 0.5)])
def test_threshold_is_alpha_times_magnitudes_plus_beta(alpha, beta):
    t = 3.0
    fw = const(t, 0.0)
    # Round-trip error e along y: bound = alpha (t^2 + t^2 + e^2) + beta.
    e_edge = np.sqrt((2 * alpha * t * t + beta) / (1 - alpha))
    inside = consistency_mask(fw, const(-t, 0.97 * e_edge), alpha, beta)
    outside = consistency_mask(fw, const(-t, 1.03 * e_edge), alpha, beta)
    assert inside[:, : W - 4].all()
    assert not outside.any()
