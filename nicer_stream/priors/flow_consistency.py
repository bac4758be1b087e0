"""Forward/backward optical-flow consistency and motion boundaries (Sundaram et al. 2010 style).

Flows are (H, W, 2) float32 (du, dv) in pixels; pixel centres are integer
coordinates (OpenCV), the image spans [-0.5, W-0.5] x [-0.5, H-0.5].
Every function here is pure: arrays in, new arrays out.
"""
from __future__ import annotations

import cv2
import numpy as np

BOUNDARY_A = 0.0005
"""Relative motion-boundary tolerance (dimensionless, 1/px^2 on |w|^2): see `motion_boundary_mask`."""
BOUNDARY_B = 0.1
"""Absolute motion-boundary tolerance on |grad u|^2 + |grad v|^2 (px/px)^2: see `motion_boundary_mask`."""
BOUNDARY_RADIUS = 2
"""Pixels rejected around a motion boundary (disc radius, px): see `motion_boundary_mask`."""


def target_coords(flow: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(H, W, 2) flow -> (x, y) float32 (H, W) coordinates p + flow(p) in the other image."""
    h, w = flow.shape[:2]
    x = np.arange(w, dtype=np.float32)[None, :] + flow[..., 0]
    y = np.arange(h, dtype=np.float32)[:, None] + flow[..., 1]
    return x.astype(np.float32), y.astype(np.float32)


def in_image_mask(flow: np.ndarray) -> np.ndarray:
    """(H, W) bool: p + flow(p) lands inside the (same-sized) other image."""
    h, w = flow.shape[:2]
    x, y = target_coords(flow)
    return (x >= -0.5) & (x <= w - 0.5) & (y >= -0.5) & (y <= h - 0.5)


def warp_backward_flow(flow_fw: np.ndarray, flow_bw: np.ndarray) -> np.ndarray:
    """(H, W, 2) backward flow sampled (bilinear) at p + flow_fw(p), i.e. f_bw(p + f_fw(p))."""
    x, y = target_coords(flow_fw)
    return cv2.remap(flow_bw.astype(np.float32), x, y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def flow_gradient_sq(flow: np.ndarray) -> np.ndarray:
    """(H, W, 2) flow -> (H, W) float32 |grad u|^2 + |grad v|^2 in (px/px)^2.

    Central differences inside the image, one-sided ones on its border (`np.gradient`);
    zero for an image less than 2 px high or wide.
    """
    if min(flow.shape[:2]) < 2:
        return np.zeros(flow.shape[:2], np.float32)
    gy, gx = np.gradient(flow.astype(np.float32, copy=False), axis=(0, 1))
    return (gx * gx + gy * gy).sum(-1)


def motion_boundary_mask(
    flow: np.ndarray, a: float = BOUNDARY_A, b: float = BOUNDARY_B, radius: int = BOUNDARY_RADIUS
) -> np.ndarray:
    """(H, W) bool, True at and near motion boundaries of the (H, W, 2) flow (pixels).

    A pixel is a boundary pixel when |grad u|^2 + |grad v|^2 > a |w|^2 + b (Sundaram et
    al. 2010, eq. 3; w = flow(p) in px, gradients in px/px by central differences); the
    boundary set is then dilated by a disc of `radius` px (0: no dilation).

    Why it is needed: DIS copies the foreground's flow onto the background for a few
    pixels next to a depth discontinuity, and does so in both directions, so the
    forward/backward check keeps those pixels although they are several pixels off.
    Their flow, however, changes fast in space.

    Why these defaults (tuned on `scripts/flow_benchmark.py --per-pair`, synthetic room
    pairs (i, i+6) at 320x240, checked but not tuned on Replica room0 at 320x181):
    - b = 0.1: |grad w| > 0.32 px/px. On well-estimated pixels (EPE < 1 px) of those
      pairs the 90th percentile of |grad w| is 0.2-0.3 px/px at 9-17 px motion, while
      the median over their > 3 px pixels is 0.6-1.2 px/px. A smaller b cost coverage on
      the small-motion pairs, a larger one kept more of the bad pixels.
    - a = 0.0005: adds |grad w| > 0.022 |w|. DIS's gradient noise grows with the motion
      (the same 90th percentile is 2-4% of |w| per px); without this term (a = 0) the
      rule discards most of the large-motion (20-35 px) pairs and makes their masked
      EPE worse. Sundaram's a = 0.01 (10% of |w| per px) let most smeared pixels
      through at 10-20 px motion (52-61% kept on the worst pair).
    - radius = 2: the smear extends a few pixels beyond where the gradient peaks (DIS
      medium matches 8x8 patches at half resolution, i.e. 16 px of support); the
      neighbours (0.00025-0.001, 0.08-0.15, 2-3) keep 8-25% of the bad pixels on the
      worst synthetic pair (17% here): the choice sits inside a plateau.
    `a` multiplies |w|^2 (px^2) and so depends on the image size: at twice the resolution
    the same `a` allows 4x more gradient (Replica at 640 px: 46% of the bad pixels kept on
    the worse 10-apart pair, against 74% without the rule).
    """
    g2 = flow_gradient_sq(flow)
    boundary = g2 > a * (flow.astype(np.float32) ** 2).sum(-1) + b
    if radius > 0:
        disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
        boundary = cv2.dilate(boundary.astype(np.uint8), disc) > 0
    return boundary


def consistency_mask(flow_fw: np.ndarray, flow_bw: np.ndarray, alpha: float = 0.005, beta: float = 0.1,
                     boundary: bool = True) -> np.ndarray:
    """(H, W) bool: forward flow agrees with the backward flow, stays in the image and is off motion boundaries.

    flow_fw, flow_bw: (H, W, 2) float flows in pixels, source -> destination and back.

    A pixel p is kept when |f_fw(p) + f_bw(p')|^2 < alpha (|f_fw(p)|^2 + |f_bw(p')|^2) + beta
    with p' = p + f_fw(p) (squared pixels): a round trip returns within about
    sqrt(beta) px plus a tolerance growing with the motion. The defaults are
    tighter than Sundaram's (0.01, 0.5): on Replica room0 frames 0 -> 19 (320 px
    wide, DIS, pixels off depth edges) this round trip alone keeps about 21% of the
    > 3 px errors instead of 37% with Sundaram's values, and 95% of the < 1 px flows
    (6% and 90% with the boundary rule below; tests/nicer_stream/priors/test_dis_flow.py).

    With `boundary` (the default) pixels of `motion_boundary_mask(flow_fw)` (BOUNDARY_A, _B,
    _RADIUS) are rejected as well: the round trip cannot see the
    flow DIS smears across depth edges consistently in both directions. Measured with
    scripts/flow_benchmark.py --per-pair (DIS, 320 px): on the synthetic room's 6-apart
    pairs the mask keeps 0.5-17% of the > 3 px pixels instead of 4-68% (coverage 35-86%
    instead of 54-92%), on Replica 0->10 and 9->19 26% instead of 46% and 37%; coverage on
    consecutive pairs drops by at most 2 points (94.5-99% synthetic, 85-95% Replica) and
    the EPE inside the mask goes down or stays on every pair. boundary=False gives the
    round trip alone.
    """
    bw = warp_backward_flow(flow_fw, flow_bw)
    err2 = ((flow_fw + bw) ** 2).sum(-1)
    bound = alpha * ((flow_fw**2).sum(-1) + (bw**2).sum(-1)) + beta
    mask = (err2 < bound) & in_image_mask(flow_fw)
    if boundary:
        mask &= ~motion_boundary_mask(flow_fw)
    return mask
