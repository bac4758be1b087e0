"""Per-frame affine brightness: the closed-form fit recovers a known gain and bias; the
corrections compose; gradients are finite."""
import math

import pytest
import torch

from nicer_stream.losses.brightness import apply_brightness, brightness_into, fit_brightness


def _image(seed=0, n=4000):
    g = torch.Generator().manual_seed(seed)
    return torch.rand(n, 3, generator=g) * 0.7 + 0.1, g


def test_fit_recovers_a_known_gain_and_bias():
    img, _ = _image()
    seen = 1.3 * img - 0.05
    a, b = fit_brightness(img, seen).tolist()
    assert abs(a - math.log(1.3)) < 2e-3 and abs(b + 0.05) < 2e-3, (math.exp(a), b)
    assert torch.allclose(apply_brightness(img, torch.tensor([a, b])), seen, atol=2e-3)
    a0, b0 = fit_brightness(img, img).tolist()  # the same exposure: (0, 0)
    assert abs(a0) < 1e-6 and abs(b0) < 1e-6


def test_a_strong_prior_pulls_the_fit_to_unit_gain_and_no_bias():
    img, _ = _image()
    weak, strong = fit_brightness(img, 1.3 * img - 0.05, prior=1e-4), fit_brightness(img, 1.3 * img - 0.05, prior=1e3)
    assert strong.abs().max() < 0.01 < weak.abs().max()


def test_masked_and_huber_fits_ignore_corrupted_pixels():
    """A fifth of the pixels replaced by unrelated colours (blur, a moving object): masked out
    they do not count; kept, the Huber-reweighted fit stays far closer than least squares."""
    img, g = _image(1)
    seen = 0.8 * img + 0.1
    bad = torch.rand(len(img), generator=g) < 0.2
    seen[bad] = torch.rand(int(bad.sum()), 3, generator=g)
    truth = torch.tensor([math.log(0.8), 0.1])
    masked = fit_brightness(img, seen, (~bad).float())
    assert (masked - truth).abs().max() < 2e-3
    l2, robust = fit_brightness(img, seen), fit_brightness(img, seen, huber_delta=0.02)
    assert (robust - truth).abs().max() < 0.5 * (l2 - truth).abs().max(), (robust, l2)
    assert (robust - truth).abs().max() < 0.05


def test_degenerate_inputs_give_finite_brightness():
    img, _ = _image()
    assert torch.equal(fit_brightness(img, img, torch.zeros(len(img))), torch.zeros(2))  # nothing counts
    flat = torch.full_like(img, 0.5)  # a textureless render: the prior keeps the 2 x 2 system solvable
    ab = fit_brightness(flat, flat + 0.1)
    assert torch.isfinite(ab).all()
    assert torch.allclose(apply_brightness(flat, ab), flat + 0.1, atol=1e-3)


def test_bringing_colours_into_another_exposure_composes():
    img, g = _image(2, 100)
    ab1, ab2 = torch.tensor([0.3, -0.05]), torch.tensor([-0.2, 0.08])
    seen1, seen2 = apply_brightness(img, ab1), apply_brightness(img, ab2)
    assert torch.allclose(brightness_into(seen1, ab1, ab2), seen2, atol=1e-6)
    assert torch.allclose(brightness_into(seen2, ab2, torch.zeros(2)), img, atol=1e-6)


def test_gradients_reach_colours_and_brightness_finite():
    img, _ = _image(3, 64)
    x = img.clone().double().requires_grad_()
    ab = torch.tensor([[0.2, -0.1], [0.0, 0.05]], dtype=torch.float64, requires_grad=True)
    out = apply_brightness(x.view(2, 32, 3), ab[:, None]).sum() + brightness_into(x, ab[0], ab[1]).sum()
    gx, gab = torch.autograd.grad(out, [x, ab])
    assert torch.isfinite(gx).all() and torch.isfinite(gab).all() and (gab != 0).all()
    assert torch.autograd.gradcheck(lambda c, p: brightness_into(c, p[0], p[1]), (x[:5], ab))


@pytest.mark.parametrize("weight_shape", ["rays", "elements"])
def test_weights_per_ray_or_per_channel(weight_shape):
    img, _ = _image(4)
    seen = 1.1 * img + 0.02
    w = torch.ones(len(img)) if weight_shape == "rays" else torch.ones_like(img)
    assert (fit_brightness(img, seen, w) - torch.tensor([math.log(1.1), 0.02])).abs().max() < 2e-3


def test_a_render_unlike_the_image_keeps_a_bounded_gain():
    """Uncorrelated colours fit a slope near 0; bounded, the gain keeps the render's gradient."""
    img, g = _image(5)
    noise = torch.rand(img.shape, generator=g)
    a, b = fit_brightness(img, noise, max_gain=4.0).tolist()
    assert abs(a + math.log(4.0)) < 1e-6  # at the bound, not near log 0
    assert abs(b - float((noise - 0.25 * img).mean())) < 1e-3  # the bias refitted for that gain
    a2, _ = fit_brightness(img, 8.0 * img, max_gain=4.0).tolist()
    assert abs(a2 - math.log(4.0)) < 1e-6
