"""Per-frame affine brightness (DSO's photometric model, as GO-SLAM and Splat-SLAM use it):
a frame's observed colour = exp(a) * radiance + b, with gain exp(a) > 0 and bias b, one pair
(a, b) per frame shared by the channels. The map holds radiance in the exposure of a
reference frame whose (a, b) is (0, 0); a real camera's auto-exposure moves the others.

`ab` is a (..., 2) tensor holding (a, b) in its last dimension.
"""
from __future__ import annotations

import math

import torch

from nicer_stream.losses.robust import huber_weights


def apply_brightness(radiance: torch.Tensor, ab: torch.Tensor) -> torch.Tensor:
    """(..., C) colours in the map's exposure and (..., 2) brightness (broadcast against the
    colours' leading dimensions, e.g. (2,) for one frame's rays) -> (..., C) as the frame sees
    them: exp(a) * radiance + b. Differentiable in both."""
    return torch.exp(ab[..., :1]) * radiance + ab[..., 1:2]


def brightness_into(colour: torch.Tensor, ab_from: torch.Tensor, ab_to: torch.Tensor) -> torch.Tensor:
    """Colours (..., C) observed by a frame with brightness `ab_from` as a frame with `ab_to`
    would observe them: exp(a_to - a_from) * (colour - b_from) + b_to (both (..., 2), broadcast
    like `apply_brightness`). The warping loss compares a frame with its partner this way."""
    return torch.exp(ab_to[..., :1] - ab_from[..., :1]) * (colour - ab_from[..., 1:2]) + ab_to[..., 1:2]


def fit_brightness(rendered: torch.Tensor, observed: torch.Tensor, weight: torch.Tensor | None = None,
                   prior: float = 1e-4, huber_delta: float = 0.0, iters: int = 3, max_gain: float = 4.0) -> torch.Tensor:
    """The (2,) brightness (a, b) that best maps `rendered` (N, C) onto `observed` (N, C):
    weighted least squares of observed ~ g * rendered + b with a ridge prior toward (g, b) =
    (1, 0) of strength `prior` per unit of weight, solved in closed form (2 x 2), a = log g.
    `weight`: (N,) or (N, C), >= 0 (None: all 1); a mask is a 0/1 weight. With `huber_delta`
    > 0, `iters` more solves reweight by Huber's IRLS weights on the residuals of the last.
    The gain is kept within [1 / max_gain, max_gain] (the bias then refitted): a render that
    does not resemble the image (an unmapped region) would otherwise fit a gain near 0, which
    would silence the pose's gradient.
    Not differentiable (a fit to hold fixed while the pose or map take their gradient step)."""
    p, t = rendered.detach().double(), observed.detach().double()
    if weight is None:
        w0 = torch.ones_like(p)
    else:
        w0 = weight.detach().double()
        w0 = (w0 if w0.dim() == p.dim() else w0[:, None]).expand_as(p)
    w = w0
    for _ in range(1 + (iters if huber_delta > 0 else 0)):
        W = float(w.sum())
        if W <= 0:
            return rendered.new_zeros(2)
        spp, sp, spt, st = float((w * p * p).sum()), float((w * p).sum()), float((w * p * t).sum()), float((w * t).sum())
        # [[spp + lam, sp], [sp, W + lam]] [g, b] = [spt + lam, st], lam = prior * W
        lam = prior * W
        a11, a12, a22 = spp + lam, sp, W + lam
        det = a11 * a22 - a12 * a12
        if not det > 0:
            return rendered.new_zeros(2)
        g = ((spt + lam) * a22 - a12 * st) / det
        b = (a11 * st - a12 * (spt + lam)) / det
        if not 1 / max_gain <= g <= max_gain:
            g = min(max(g, 1 / max_gain), max_gain)
            b = (st - g * sp) / a22
        w = w0 * huber_weights(g * p + b - t, huber_delta) if huber_delta > 0 else w0
    return rendered.new_tensor([math.log(g), b])
