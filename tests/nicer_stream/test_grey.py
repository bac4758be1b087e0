"""The grey copies: luminance weights, uint8 rounding, grey input passed through."""
import numpy as np

from nicer_stream.grey import to_grey_f32, to_grey_u8


def test_grey_copies_weigh_the_channels_as_luminance_and_agree_with_each_other():
    rgb = np.random.default_rng(0).random((6, 7, 3)).astype(np.float32)
    f = to_grey_f32(rgb)
    np.testing.assert_allclose(f, rgb @ np.array([0.299, 0.587, 0.114], np.float32), atol=1e-5)
    assert np.abs(to_grey_u8(rgb).astype(np.float32) - f * 255).max() <= 1.0  # rounded to integers


def test_grey_images_pass_through_in_their_own_scale():
    u8 = np.arange(12, dtype=np.uint8).reshape(3, 4) * 20
    assert to_grey_u8(u8) is u8
    np.testing.assert_allclose(to_grey_f32(u8), u8 / 255.0, atol=1e-7)
    f = np.full((3, 4), 0.25)
    np.testing.assert_array_equal(to_grey_f32(f), np.float32(0.25))
