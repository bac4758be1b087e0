"""Closed-form checks of the forward/backward consistency mask and of the motion-boundary rule."""
from __future__ import annotations

import numpy as np
import pytest

from nicer_stream.priors.flow_consistency import (
    BOUNDARY_A,
    BOUNDARY_B,
    BOUNDARY_RADIUS,
    consistency_mask,
    flow_gradient_sq,
    in_image_mask,
    motion_boundary_mask,
    warp_backward_flow,
)

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


def step_flow(du: float, col: int) -> np.ndarray:
    """u = 0 left of column `col`, u = du from it on (a motion boundary between col-1 and col); v = 0."""
    f = np.zeros((H, W, 2), np.float32)
    f[:, col:, 0] = du
    return f


def test_motion_boundary_rejects_a_step_edge_and_keeps_flat_regions():
    col, du = 10, 5.0
    fw = step_flow(du, col)
    # Central differences see the 5 px step on columns col-1 and col: |grad u|^2 = 2.5^2,
    # far above a |w|^2 + b there; the flat columns have zero gradient.
    core = motion_boundary_mask(fw, radius=0)
    expected = np.zeros((H, W), bool)
    expected[:, col - 1 : col + 1] = True
    np.testing.assert_array_equal(core, expected)
    # The default radius (2 px disc) widens it by 2 columns each side; everything else is kept.
    dilated = motion_boundary_mask(fw)
    expected[:, col - 1 - BOUNDARY_RADIUS : col + 1 + BOUNDARY_RADIUS] = True
    np.testing.assert_array_equal(dilated, expected)
    assert dilated[:, : col - 1 - BOUNDARY_RADIUS].sum() == 0 and dilated[:, col + 1 + BOUNDARY_RADIUS :].sum() == 0


def test_motion_boundary_keeps_a_small_step():
    """A 0.5 px step (|grad u| = 0.25 px/px < sqrt(b) = 0.32) is within DIS's noise: not a boundary."""
    assert not motion_boundary_mask(step_flow(0.5, 10)).any()


def test_motion_boundary_tolerance_grows_with_the_motion():
    """u = t + k x has |grad u|^2 = k^2 everywhere: a boundary exactly where k^2 > a (t + k x)^2 + b."""
    t, k, a, b = 10.0, 0.5, BOUNDARY_A, BOUNDARY_B
    x = np.arange(W, dtype=np.float32)[None, :].repeat(H, 0)
    fw = np.stack([t + k * x, np.zeros_like(x)], -1)
    got = motion_boundary_mask(fw, a, b, radius=0)
    expected = k * k > a * (t + k * x) ** 2 + b  # here: columns with u < sqrt((k^2 - b) / a) = 17.3 px
    assert expected.any() and not expected.all()  # the relative term decides inside the image
    np.testing.assert_array_equal(got, expected)
    assert not motion_boundary_mask(fw, a=0.01, b=b, radius=0).any()  # Sundaram's a = 0.01 keeps it all


def test_consistency_mask_rejects_a_round_trip_consistent_motion_boundary():
    """A step flow whose backward flow undoes it exactly passes the round trip but not the boundary rule."""
    col, du = 10, 5.0
    fw = step_flow(du, col)
    bw = np.zeros_like(fw)
    bw[:, col + int(du) :, 0] = -du  # destination columns >= col + du came from the moving part
    round_trip = consistency_mask(fw, bw, boundary=False)
    np.testing.assert_array_equal(round_trip, in_image_mask(fw))  # consistent everywhere it lands inside
    mask = consistency_mask(fw, bw)
    np.testing.assert_array_equal(mask, round_trip & ~motion_boundary_mask(fw))
    assert not mask[:, col - 3 : col + 3].any()
    assert mask[:, : col - 3].all() and mask[:, col + 3 : W - int(du)].all()


def test_motion_boundary_is_pure_and_handles_tiny_images():
    fw = step_flow(5.0, 10)
    before = fw.copy()
    motion_boundary_mask(fw)
    np.testing.assert_array_equal(fw, before)
    assert flow_gradient_sq(np.ones((1, 7, 2), np.float32)).shape == (1, 7)
    assert not motion_boundary_mask(np.ones((1, 7, 2), np.float32)).any()
