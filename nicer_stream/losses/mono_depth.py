"""Monocular depth loss with scale-and-shift alignment (paper Eq. 10, MonoSDF).

The prior depth is relative (unknown scale and shift), so the rendered depth D
is aligned to it, w * D + q, before a squared error. (w, q) come from a
closed-form least-squares fit per image and are treated as constants
(no gradient), as in MonoSDF.
"""
from __future__ import annotations

import torch

from nicer_stream.losses.photometric import masked_mean

# Relative variance below which the rendered depth is treated as constant.
_VAR_EPS = 1e-10


def masked_moments(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor | None):
    """Float64 count, means, var(pred) and cov(pred, target) over the mask along the last
    dimension (no grad): (N,) inputs give 0-dim tensors, (R, N) one value per row."""
    p, t = pred.detach().double(), target.detach().double()
    m = torch.ones_like(p, dtype=torch.bool) if mask is None else mask.to(torch.bool)
    m = m & torch.isfinite(p) & torch.isfinite(t)
    n = m.sum(-1)
    nf = n.clamp_min(1).double()
    p, t = torch.where(m, p, 0.0), torch.where(m, t, 0.0)
    mp, mt = p.sum(-1) / nf, t.sum(-1) / nf
    # Centred sums: better conditioned than the raw normal equations.
    dp, dt = torch.where(m, p - mp[..., None], 0.0), torch.where(m, t - mt[..., None], 0.0)
    return n, mp, mt, (dp * dp).sum(-1) / nf, (dp * dt).sum(-1) / nf


def degenerate_fit(n: torch.Tensor, mean_p: torch.Tensor, var_p: torch.Tensor) -> torch.Tensor:
    """Element-wise over `masked_moments`' outputs: fewer than 2 samples, or a (numerically)
    constant prediction (no unique (w, q))."""
    return (n < 2) | (var_p <= _VAR_EPS * (1.0 + mean_p * mean_p))


def scale_shift_lstsq(
    pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor | None = None
) -> tuple[torch.Tensor, torch.Tensor]:
    """Closed-form (w, q) minimising sum over mask of (w * pred + q - target)^2.

    pred: (N,) rendered z-depth; target: (N,) prior depth; mask: (N,) bool or None.
    Returns detached 0-dim tensors in pred's dtype/device. Non-finite entries
    are ignored. Degenerate input (< 2 valid samples or constant pred) has no
    unique solution: returns the identity (1, 0).
    """
    n, mp, mt, var_p, cov = masked_moments(pred, target, mask)
    if degenerate_fit(n, mp, var_p):
        w, q = torch.ones((), dtype=torch.float64), torch.zeros((), dtype=torch.float64)
    else:
        w = cov / var_p
        q = mt - w * mp
    return w.to(pred), q.to(pred)


def mono_depth_loss(
    pred_depth: torch.Tensor,
    prior_depth: torch.Tensor,
    mask: torch.Tensor | None = None,
    fixed_scale_shift: tuple[float, float] | None = None,
) -> torch.Tensor:
    """Mean over mask of (w * pred_depth + q - prior_depth)^2.

    pred_depth: (N,) rendered z-depth (differentiable); prior_depth: (N,)
    relative monocular depth; mask: (N,) bool or None.
    fixed_scale_shift: (w, q) to use instead of the fit; the paper uses
    (20, 0) in the first mapping step, when the rendered depth is still the
    initial sphere and a fit would be meaningless.
    Returns a 0-dim tensor; 0 (no NaN) on degenerate input when fitting.
    """
    valid = torch.isfinite(prior_depth)
    valid = valid if mask is None else valid & mask.to(torch.bool)
    if fixed_scale_shift is not None:
        w, q = fixed_scale_shift
    else:
        n, mp, _, var_p, _ = masked_moments(pred_depth, prior_depth, valid)
        if degenerate_fit(n, mp, var_p):
            # Zero that stays on the graph, so it can be summed into a total loss.
            return torch.nan_to_num(pred_depth).sum() * 0.0
        w, q = scale_shift_lstsq(pred_depth, prior_depth, valid)
    residual = w * pred_depth + q - torch.where(valid, prior_depth, 0.0)
    return masked_mean(residual * residual, valid)
