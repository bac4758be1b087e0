"""Dense depth from posed images alone: plane-sweep multi-view stereo (no ground truth, no weights).

For a reference image and one or more partner images with known T_world_cam poses, every
fronto-parallel plane z = d of the reference camera maps the reference pixels into a partner by
the homography H(d) = K (R + t n^T / d) K^-1 (R, t: reference camera to partner camera,
n = (0, 0, 1)). The partner warped by H(d) is compared with the reference by zero-mean
normalised cross-correlation (ZNCC) in a small window; the plane with the lowest cost wins, and
a parabola through its neighbours refines it between planes. Planes are uniform in inverse depth,
about one pixel of disparity apart for the widest baseline.

Why plane sweep rather than rectified two-view matching: it needs no rectification, so it works
for any motion (forward motion puts the epipole inside the image, where rectification breaks),
and it takes several partners at once: a pixel occluded in one partner uses the other (the
cost is the minimum over partners).

A pixel is confident when its window has texture, its best ZNCC is high, the partners that
see it agree on the plane, and the best plane is not at an end of the range. Unconfident
pixels get depth 0.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from nicer_stream.config import StereoConfig
from nicer_stream.grey import to_grey_f32
from nicer_stream.priors.base import NoDepthNormal
from nicer_stream.types import Intrinsics


def shrink_depth(depth: np.ndarray, width: int, height: int) -> np.ndarray:
    """(H, W) z-depth with 0 where unknown -> (height, width): the mean of the known depths under
    each output pixel, 0 where fewer than half of them are known."""
    known = (depth > 0).astype(np.float32)
    total = cv2.resize(depth.astype(np.float32) * known, (width, height), interpolation=cv2.INTER_AREA)
    share = cv2.resize(known, (width, height), interpolation=cv2.INTER_AREA)
    return np.where(share >= 0.5, total / np.maximum(share, 1e-6), 0.0).astype(np.float32)


def drop_depth_edges(depth: np.ndarray, window: int, max_rel: float) -> np.ndarray:
    """(H, W) z-depth, 0 where unknown -> the same with 0 wherever the known depths in the
    `window` x `window` square around a pixel span more than `max_rel` of their smallest. Why: a
    matching window that straddles a depth edge takes the nearer surface's texture, so the
    foreground spreads over the background beside every edge (Replica, GT poses: the largest
    share of the sweep's L1). window < 2 keeps everything."""
    if window < 2:
        return depth
    known = depth > 0
    kernel = np.ones((window, window), np.uint8)
    top = cv2.dilate(np.where(known, depth, 0.0).astype(np.float32), kernel)
    bottom = cv2.erode(np.where(known, depth, 1e30).astype(np.float32), kernel)
    return np.where(known & (top <= bottom * (1.0 + max_rel)), depth, 0.0).astype(np.float32)


def drop_speckles(depth: np.ndarray, max_size: int, max_step: float) -> np.ndarray:
    """(H, W) z-depth, 0 where unknown -> the same with 0 on connected blobs of fewer than
    `max_size` pixels, neighbours joined where their inverse depths differ by at most
    `max_step` of the median inverse depth: small islands of consistent but wrong matches (as
    `cv2.StereoSGBM`'s speckle filter). max_size < 1 keeps everything."""
    known = depth > 0
    if max_size < 1 or not known.any():
        return depth
    inv = np.where(known, 1.0 / np.maximum(depth, 1e-9), 0.0)
    unit = float(np.median(inv[known])) * max_step / 16.0  # filterSpeckles takes int16 steps
    disparity = np.round(inv / unit).clip(0, 32767).astype(np.int16)
    cv2.filterSpeckles(disparity, 0, int(max_size), 16)
    return np.where(known & (disparity != 0), depth, 0.0).astype(np.float32)


def plane_homography(K: np.ndarray, T_partner_ref: np.ndarray, depth: float) -> np.ndarray:
    """(3, 3) map of reference pixels (homogeneous) to partner pixels for the plane z = depth
    of the reference camera. T_partner_ref (4, 4): reference camera to partner camera."""
    R, t = T_partner_ref[:3, :3], T_partner_ref[:3, 3:4]
    n = np.array([[0.0, 0.0, 1.0]])
    return K @ (R + t @ n / depth) @ np.linalg.inv(K)


def _box(x: np.ndarray, w: int) -> np.ndarray:
    return cv2.boxFilter(x, -1, (w, w), normalize=True, borderType=cv2.BORDER_REFLECT)


def local_std(grey: np.ndarray, window: int) -> np.ndarray:
    """(H, W) float grey image -> (H, W) standard deviation of its `window` x `window` square."""
    mean = _box(grey, window)
    return np.sqrt(np.maximum(_box(grey * grey, window) - mean * mean, 0.0))


def zncc(a: np.ndarray, mean_a: np.ndarray, std_a: np.ndarray, b: np.ndarray, w: int) -> np.ndarray:
    """Windowed ZNCC (H, W) of images a and b; a's window mean and std given (computed once)."""
    mean_b = _box(b, w)
    var_b = np.maximum(_box(b * b, w) - mean_b * mean_b, 0.0)
    cov = _box(a * b, w) - mean_a * mean_b
    return cov / np.maximum(std_a * np.sqrt(var_b), 1e-6)


def plane_count(intr: Intrinsics, baselines: list[float], near: float, far: float, p: StereoConfig) -> int:
    """Planes ~1 px of disparity apart for the widest baseline, clipped to [min, max]."""
    span_px = max(intr.fx, intr.fy) * max(baselines) * (1.0 / near - 1.0 / far)
    return int(np.clip(np.ceil(span_px), p.min_planes, p.max_planes))


# The window and the filters' sizes were tuned on 640 px sweeps; a larger sweep scales them so
# that they keep their extent in the scene (and a smaller one keeps them as they are).
TUNED_SIDE = 640


def _odd(x: float) -> int:
    return 2 * int(round((x - 1) / 2)) + 1


def scaled_to(params: StereoConfig, side: int) -> StereoConfig:
    """`params` with `window`, `edge_window` (pixels) and `speckle_size` (pixels, an area) scaled
    by side / TUNED_SIDE when the sweep's longer side `side` exceeds TUNED_SIDE."""
    s = side / TUNED_SIDE
    if s <= 1.0:
        return params
    return replace(params, window=_odd(params.window * s),
                   edge_window=_odd(params.edge_window * s) if params.edge_window >= 2 else params.edge_window,
                   speckle_size=int(round(params.speckle_size * s * s)))


@dataclass
class BestPlanes:
    """Per pixel (H, W): the best plane k of the cost over partners (the minimum over them), its
    cost c0, the costs of planes k - 1 and k + 1 (cm, cp; any value at the range's ends), and
    whether every partner that sees the pixel at plane k puts its own best within
    `max_plane_disagreement` planes of k (agree: on a blank wall every depth matches and the
    partners' choices scatter)."""

    k: np.ndarray
    c0: np.ndarray
    cm: np.ndarray
    cp: np.ndarray
    agree: np.ndarray


def best_planes_reference(costs: np.ndarray, max_disagreement: int) -> BestPlanes:
    """BestPlanes from the whole cost volume (partners, planes, H, W)."""
    n, h, wd = costs.shape[1:]
    cost = costs.min(0)  # occluded or outside in one partner: the other decides
    k = np.argmin(cost, axis=0)
    rows, cols = np.indices((h, wd))
    agree = np.ones((h, wd), bool)
    if len(costs) > 1:
        for cj in costs:
            seen = cj[k, rows, cols] < 2.0
            agree &= ~seen | (np.abs(np.argmin(cj, axis=0) - k) <= max_disagreement)
    km, kp = np.clip(k - 1, 0, n - 1), np.clip(k + 1, 0, n - 1)
    return BestPlanes(k, cost[k, rows, cols], cost[km, rows, cols], cost[kp, rows, cols], agree)


def best_planes_streaming(planes, max_disagreement: int) -> BestPlanes:
    """BestPlanes from the planes' costs in order (an iterable of per-partner lists of (H, W)
    costs), keeping a few images instead of the (partners, planes, H, W) volume (200 MB and
    ~1 s of argmins at 960 x 544 with 48 planes and two partners). The first minimum wins ties,
    as `np.argmin` does: the same result as `best_planes_reference`."""
    for i, cs in enumerate(planes):
        joint = np.minimum.reduce(cs) if len(cs) > 1 else cs[0]
        if i == 0:
            k = np.zeros(joint.shape, np.int32)
            c0, cm, cp, prev = joint.copy(), joint.copy(), joint.copy(), joint
            at_k = [c.copy() for c in cs]  # each partner's cost at plane k
            best = [c.copy() for c in cs]  # each partner's own best cost and plane
            arg = [np.zeros(joint.shape, np.int32) for _ in cs]
            fresh = np.ones(joint.shape, bool)  # k == i - 1 at the next plane
            continue
        np.copyto(cp, joint, where=fresh)
        for c, b, a in zip(cs, best, arg):
            u = c < b
            np.copyto(b, c, where=u)
            np.copyto(a, i, where=u)
        u = joint < c0
        np.copyto(cm, prev, where=u)
        np.copyto(c0, joint, where=u)
        np.copyto(k, i, where=u)
        for c, ak in zip(cs, at_k):
            np.copyto(ak, c, where=u)
        fresh, prev = u, joint
    agree = np.ones(k.shape, bool)
    if len(at_k) > 1:
        for ak, a in zip(at_k, arg):
            agree &= ~(ak < 2.0) | (np.abs(a - k) <= max_disagreement)
    return BestPlanes(k, c0, cm, cp, agree)


def sweep_depth(ref_rgb: np.ndarray, T_world_ref: np.ndarray, partners: list[tuple[np.ndarray, np.ndarray]],
                intr: Intrinsics, near: float, far: float,
                params: StereoConfig = StereoConfig(), volume: bool = False) -> np.ndarray:
    """Plane-sweep depth of the reference image.

    ref_rgb (H, W, 3) float [0, 1] or (H, W) grey (`to_grey_f32`); T_world_ref (4, 4) T_world_cam; partners:
    (image of the same kind and size, T_world_cam (4, 4)) pairs, same intrinsics `intr`; near < far: the z-depth range searched,
    in the poses' unit. Returns the z-depth (H, W) float32 in the poses' unit, 0 where not
    confident. `volume`: keep the whole cost volume (`best_planes_reference`; always with
    `min_uniqueness`), else stream the planes (`best_planes_streaming`, the same result)."""
    if not partners:
        raise ValueError("plane sweep needs at least one partner image")
    (h, wd) = ref_rgb.shape[:2]
    params = scaled_to(params, max(h, wd))
    w = params.window
    K = intr.matrix()
    a = to_grey_f32(ref_rgb)
    mean_a, std_a = _box(a, w), local_std(a, w)
    rel = [np.linalg.inv(T) @ T_world_ref for _, T in partners]
    n = plane_count(intr, [float(np.linalg.norm(T[:3, 3])) for T in rel], near, far, params)
    inv_d = np.linspace(1.0 / near, 1.0 / far, n)
    greys = [to_grey_f32(rgb) for rgb, _ in partners]
    ones = np.ones((h, wd), np.float32)

    def plane_costs(d: float) -> list[np.ndarray]:
        """Cost 1 - ZNCC per partner for the plane at z-depth d; 2 (worse than any match) where
        a window is not wholly inside the partner's image."""
        out = []
        for g, T in zip(greys, rel):
            H = plane_homography(K, T, d)
            warped = cv2.warpPerspective(g, H, (wd, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)
            inside = _box(cv2.warpPerspective(ones, H, (wd, h), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP), w) > 0.999
            out.append(np.where(inside, 1.0 - zncc(a, mean_a, std_a, warped, w), 2.0).astype(np.float32, copy=False))
        return out

    costs = None
    if volume or params.min_uniqueness > 0:
        costs = np.stack([np.stack(plane_costs(d)) for d in 1.0 / inv_d], axis=1)
        best = best_planes_reference(costs, params.max_plane_disagreement)
    else:
        best = best_planes_streaming((plane_costs(d) for d in 1.0 / inv_d), params.max_plane_disagreement)
    k, c0 = best.k, best.c0
    # Parabola through the best plane and its neighbours: sub-plane inverse depth.
    denom = best.cm - 2 * c0 + best.cp
    off = np.where((k > 0) & (k < n - 1) & (denom > 1e-9), 0.5 * (best.cm - best.cp) / np.maximum(denom, 1e-9), 0.0)
    step = inv_d[1] - inv_d[0] if n > 1 else 0.0
    depth = 1.0 / (inv_d[k] + np.clip(off, -0.5, 0.5) * step)
    ok = (std_a >= params.min_texture) & (c0 <= 1.0 - params.min_ncc)
    ok &= best.agree & (c0 < 2.0) & (k > 0) & (k < n - 1)  # seen by a partner; not at the ends of the range
    if params.min_uniqueness > 0:  # c0 is the minimum: a bound of 0 rejects nothing
        # Runner-up: the lowest cost at least 2 planes from the best.
        planes = np.arange(n)[:, None, None]
        far_cost = np.where(np.abs(planes - k[None]) >= 2, costs.min(0), np.inf).min(0)
        ok &= far_cost - c0 >= params.min_uniqueness
    depth = np.where(ok, depth, 0.0).astype(np.float32)
    depth = drop_speckles(depth, params.speckle_size, params.speckle_step)
    return drop_depth_edges(depth, params.edge_window, params.edge_rel)


class StereoDepthNormal(NoDepthNormal):
    """`--priors stereo`: nothing per frame; the SLAM computes each keyframe's depth and normals
    by plane sweep once it has posed neighbours (`priors/keyframe_stereo.py`)."""

    name = "stereo"
    description = "stereo (plane-sweep depth from keyframes and the SLAM's own poses; no ground truth, no weights)"
