"""RGB warping loss (paper Sec. 3.3): reproject pixels with rendered depth into
other frames and compare the observed colours there.

Conventions: pixels are (u, v) with integer values at pixel centres; depth is
z-depth in metres; poses are T_world_cam (camera-to-world, 4x4).
"""
from __future__ import annotations

from typing import Sequence

import torch

from nicer_stream.geometry.camera import in_image, project, unproject
from nicer_stream.geometry.se3 import invert, transform_points
from nicer_stream.losses.brightness import brightness_into
from nicer_stream.losses.photometric import masked_mean
from nicer_stream.losses.robust import robust_l1
from nicer_stream.types import Intrinsics


def warp_pixels(
    uv_src: torch.Tensor,
    depth_src: torch.Tensor,
    intr_src: Intrinsics,
    T_world_src: torch.Tensor,
    intr_dst: Intrinsics,
    T_world_dst: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Where source pixels with known z-depth appear in a destination camera.

    uv_src: (N, 2) source pixels; depth_src: (N,) z-depth in the source camera.
    T_world_src, T_world_dst: (4, 4) camera-to-world poses (cast to depth's dtype).
    Returns uv_dst (N, 2) pixels, z_dst (N,) z-depth in the destination camera,
    valid (N,) bool: source depth > 0, z_dst > 0 and uv_dst inside the image.
    Differentiable w.r.t. depth_src and both poses.
    """
    dtype = depth_src.dtype
    T_dst_src = invert(T_world_dst.to(dtype)) @ T_world_src.to(dtype)
    p_src = unproject(uv_src.to(dtype), depth_src, intr_src)
    p_dst = transform_points(T_dst_src, p_src)
    uv_dst, z_dst = project(p_dst, intr_dst)
    valid = (depth_src > 0) & (z_dst > 0) & in_image(uv_dst, intr_dst)
    return uv_dst, z_dst, valid


def bilinear_sample(image: torch.Tensor, uv: torch.Tensor) -> torch.Tensor:
    """Bilinearly sample (H, W, C) `image` at (N, 2) pixels `uv` -> (N, C).

    Integer (u, v) are pixel centres, so uv = (u, v) returns image[v, u]
    exactly. Coordinates are clamped to the outermost pixel centres (border
    replication), which keeps out-of-image samples finite; callers mask them.
    Differentiable w.r.t. uv (and image).
    """
    H, W, C = image.shape
    return bilinear_sample_rows(image.reshape(H * W, C), H, W, uv)


def bilinear_sample_rows(rows: torch.Tensor, H: int, W: int, uv: torch.Tensor,
                         first_row: torch.Tensor | None = None) -> torch.Tensor:
    """`bilinear_sample` of images stored as rows: (K * H * W, C) `rows` holds K images of
    H x W in row-major order; pixel i of `uv` (N, 2) is read from the image starting at row
    `first_row[i]` (N,) int64 (None: 0, a single image) -> (N, C)."""
    u = uv[:, 0].to(rows.dtype).clamp(0, W - 1)
    v = uv[:, 1].to(rows.dtype).clamp(0, H - 1)
    # Top-left neighbour, kept one pixel from the far edge so +1 stays in range.
    u0 = u.detach().floor().clamp(0, max(W - 2, 0))
    v0 = v.detach().floor().clamp(0, max(H - 2, 0))
    au, av = (u - u0)[:, None], (v - v0)[:, None]
    iu0, iv0 = u0.long(), v0.long()
    iu1, iv1 = (iu0 + 1).clamp(max=W - 1), (iv0 + 1).clamp(max=H - 1)
    r0, r1 = iv0 * W, iv1 * W
    if first_row is not None:
        r0, r1 = r0 + first_row, r1 + first_row
    c00, c01 = rows[r0 + iu0], rows[r0 + iu1]
    c10, c11 = rows[r1 + iu0], rows[r1 + iu1]
    top = c00 * (1 - au) + c01 * au
    bottom = c10 * (1 - au) + c11 * au
    return top * (1 - av) + bottom * av


def warping_loss(
    rgb_src: torch.Tensor,
    images_dst: Sequence[torch.Tensor],
    uv_dst: Sequence[torch.Tensor],
    valid: Sequence[torch.Tensor],
    huber_delta: float = 0.0,
    brightness_src: torch.Tensor | None = None,
    brightness_dst: Sequence[torch.Tensor] | None = None,
) -> torch.Tensor:
    """Mean over valid (ray, destination frame) pairs of |C_src - C_dst(uv_dst)|_1 (with
    `huber_delta` > 0: the Huber-smoothed norm `robust.robust_l1`).

    rgb_src: (N, 3) observed colours at the source pixels.
    images_dst: per destination frame, (H, W, 3) observed image.
    uv_dst, valid: per destination frame, (N, 2) warped pixels and (N,) bool
        from `warp_pixels`.
    brightness_src (2,), brightness_dst: per destination frame (2,): the frames' affine
        brightness (a, b) (`losses/brightness.py`); when given, each destination colour is
        brought into the source's exposure before the comparison (differentiable in both).
    Returns a 0-dim tensor, 0 when no pair is valid. The gradient reaches the
    depth and poses through uv_dst (image gradients of the destination frame).
    """
    if not (len(images_dst) == len(uv_dst) == len(valid)):
        raise ValueError("images_dst, uv_dst and valid must have one entry per destination frame")
    if not images_dst:
        return rgb_src.sum() * 0.0
    seen = [bilinear_sample(img, uv).to(rgb_src.dtype) for img, uv in zip(images_dst, uv_dst)]
    if brightness_src is not None and brightness_dst is not None:
        seen = [brightness_into(c, ab, brightness_src) for c, ab in zip(seen, brightness_dst)]
    errors = [robust_l1(c - rgb_src, huber_delta) for c in seen]
    return masked_mean(torch.cat(errors), torch.cat([m.to(torch.bool) for m in valid]))
