"""Which gradient samples can matter: those the light still reaches.

A sample behind a surface, where the transmittance T has fallen below a small threshold, adds
at most T to its ray's weights, and every gradient through it is scaled by T as well. Its SDF,
normal and colour (the network with gradient: most of an iteration) can be left out. T is
estimated before that network runs, from the SDF the probe pass already has: linear between
the two probes around each sample (an SDF is close to linear along a ray near a surface).

On a Replica map after 300 mapping iterations (`fast`, 1024 rays x 16 samples), T < 1e-4
marks 20% of the samples; the exact weights of those it marks sum to at most 7e-4 per ray.

Tracking uses it (`[tracking] min_transmittance`). Mapping does not by default: there the
samples behind surfaces also carry the Eikonal term, and without them the Replica map lost
depth accuracy on three seeds (docs/decisions.md).
"""
from __future__ import annotations

import torch

from nicer_stream.render.density import laplace_density
from nicer_stream.render.probe import composite_deltas
from nicer_stream.render.volume import transmittance


def interpolate_along_rays(t_knots: torch.Tensor, values: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """Piecewise-linear interpolation per ray: knots t_knots (R, P) sorted with values (R, P),
    queried at t (R, S) -> (R, S); constant beyond the first and last knot."""
    p = t_knots.shape[1]
    k = torch.searchsorted(t_knots.contiguous(), t.contiguous(), right=True)  # first knot after t
    k0, k1 = (k - 1).clamp(0, p - 1), k.clamp(0, p - 1)
    t0, t1 = t_knots.gather(1, k0), t_knots.gather(1, k1)
    v0, v1 = values.gather(1, k0), values.gather(1, k1)
    a = ((t - t0) / (t1 - t0).clamp_min(1e-12)).clamp(0, 1)
    return v0 + a * (v1 - v0)


@torch.no_grad()
def live_mask(sdf_est: torch.Tensor, beta_t: torch.Tensor | float, t: torch.Tensor, far: torch.Tensor,
              min_transmittance: float, keep_band: float = 0.0) -> torch.Tensor:
    """(R, S) bool: samples whose estimated transmittance is at least `min_transmittance`, or
    whose estimated SDF is above -`keep_band` (just behind a surface; 0: none kept for that).
    sdf_est (R, S) at the sorted samples t (R, S); beta_t their betas ((R, S) or a scalar);
    far (R,). The first sample of every ray is always live (T = 1 there)."""
    live = transmittance(laplace_density(sdf_est, beta_t), composite_deltas(t, far)) >= min_transmittance
    return live | (sdf_est > -keep_band) if keep_band > 0 else live


# The network's row count is rounded up to a multiple of this: oneDNN builds a kernel for each
# new matrix shape (a few ms each), so a different count every iteration cost more than the
# rows saved (tracking 0.075 -> 0.082 s per iteration with 15% of its samples left out).
ROW_BUCKET = 512


def kept_indices(live: torch.Tensor, bucket: int = ROW_BUCKET) -> torch.Tensor | None:
    """Flat indices (M,) of the samples to evaluate: every live one (live: (N,) bool), then
    the first dead ones up to M = a multiple of `bucket` (or N); None when that is all N."""
    n, n_live = live.numel(), int(live.sum())
    m = min(n, -(-n_live // bucket) * bucket)
    if m == n:
        return None
    idx = live.nonzero()[:, 0]
    if m > n_live:
        idx = torch.cat([idx, (~live).nonzero()[: m - n_live, 0]])
    return idx
