"""Optical-flow loss (paper Sec. 3.3): rendered correspondence vs. flow prior."""
from __future__ import annotations

import torch

from nicer_stream.losses.photometric import masked_mean


def flow_loss(
    uv_src: torch.Tensor,
    uv_dst_rendered: torch.Tensor,
    flow_prior: torch.Tensor,
    valid: torch.Tensor,
) -> torch.Tensor:
    """Mean over valid rays of |(uv_dst_rendered - uv_src) - flow_prior|_1.

    uv_src: (N, 2) source pixels (pixel-centre convention).
    uv_dst_rendered: (N, 2) where the rendered depth and the poses warp them
        in the destination frame (`warp_pixels`), differentiable.
    flow_prior: (N, 2) prior flow (du, dv) in pixels sampled at uv_src.
    valid: (N,) bool: warp in image and flow reliable.
    Returns a 0-dim tensor, 0 when no ray is valid.
    """
    residual = (uv_dst_rendered - uv_src) - flow_prior
    return masked_mean(residual.abs().sum(dim=-1), valid)
