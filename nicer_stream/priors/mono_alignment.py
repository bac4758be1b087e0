"""A monocular depth prior aligned to multi-view depth by a smooth scale field, and the two fused.

A monocular network's depth is relative (an unknown scale and shift per image) and, after the
best per-image affine fit, still off by a smooth, image-wide distortion (AbsRel 0.08-0.11 for
DPT-class networks indoors: tens of centimetres at room depth). Multi-view stereo between
keyframes is metric in the poses' unit and accurate where it is confident, but blank walls,
depth edges and occlusions leave it with holes. Here the monocular depth is fitted to the
confident stereo depth with a per-pixel scale that varies bilinearly over a coarse grid of
nodes plus one shift (`align_depth`), and the holes (and the stereo pixels far from the fit) are
filled with the fitted monocular depth (`fuse_depth`): the stereo's accuracy where it has depth,
the network's shape elsewhere, both in the poses' unit.
"""
from __future__ import annotations

import numpy as np


def grid_shape(width: int, height: int, cells: int) -> tuple[int, int]:
    """(rows, cols) of nodes: `cells` cells across the longer side, square-ish cells."""
    long = max(width, height)
    rows = max(1, round(cells * height / long)) + 1
    cols = max(1, round(cells * width / long)) + 1
    return rows, cols


def bilinear_weights(height: int, width: int, rows: int, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """Each pixel's four grid nodes and their bilinear weights over a (rows, cols) grid whose
    corner nodes sit on the image's corner pixels: (H*W, 4) int node indices (row-major) and
    (H*W, 4) float64 weights summing to 1."""
    ys = np.linspace(0.0, rows - 1.0, height)
    xs = np.linspace(0.0, cols - 1.0, width)
    y0 = np.clip(np.floor(ys).astype(int), 0, max(rows - 2, 0))
    x0 = np.clip(np.floor(xs).astype(int), 0, max(cols - 2, 0))
    fy, fx = (ys - y0)[:, None], (xs - x0)[None, :]
    idx, wts = [], []
    for dy, wy in ((0, 1.0 - fy), (1, fy)):
        for dx, wx in ((0, 1.0 - fx), (1, fx)):
            r = np.minimum(y0 + dy, rows - 1)[:, None]
            c = np.minimum(x0 + dx, cols - 1)[None, :]
            idx.append(np.broadcast_to(r * cols + c, (height, width)).ravel())
            wts.append(np.broadcast_to(wy * wx, (height, width)).ravel())
    return np.stack(idx, 1), np.stack(wts, 1)


def _smoothness(rows: int, cols: int) -> np.ndarray:
    """(E, rows*cols) differences between neighbouring nodes (right and down)."""
    ids = np.arange(rows * cols).reshape(rows, cols)
    a = np.concatenate([ids[:, :-1].ravel(), ids[:-1].ravel()])  # each node and its right / lower neighbour
    b = np.concatenate([ids[:, 1:].ravel(), ids[1:].ravel()])
    out = np.zeros((len(a), rows * cols))
    out[np.arange(len(a)), a], out[np.arange(len(a)), b] = 1.0, -1.0
    return out


def align_depth(mono: np.ndarray, metric: np.ndarray, cells: int = 7, smooth: float = 1e-4,
                iters: int = 4, min_known: float = 0.05) -> np.ndarray | None:
    """The monocular depth `mono` (H, W) mapped onto `metric` (H, W; 0 where unknown):
    s(u, v) * mono + q, s bilinear over a `grid_shape(W, H, cells)` grid of nodes, q one shift,
    fitted by least squares on the known pixels with `smooth` * (sum of weights) * median(mono)^2
    times the squared differences of neighbouring nodes (nodes without data follow their
    neighbours) and `iters` reweightings that cap each residual's weight beyond twice its robust
    spread (stereo's gross errors). Returns the (H, W) float32 aligned depth, NaN where `mono` is
    not finite or the fit puts it at or behind the camera; None when fewer than `min_known` of
    the pixels are known or the fit puts half of them at or behind the camera."""
    h, w = mono.shape
    known = (metric > 0) & np.isfinite(mono)
    if known.mean() < min_known:
        return None
    rows, cols = grid_shape(w, h, cells)
    n = rows * cols
    idx, wts = bilinear_weights(h, w, rows, cols)
    sel = known.ravel()
    m = mono.ravel().astype(np.float64)
    A = np.zeros((int(sel.sum()), n + 1))
    np.put_along_axis(A, idx[sel], wts[sel] * m[sel, None], axis=1)
    A[:, n] = 1.0
    y = metric.ravel()[sel].astype(np.float64)
    D = _smoothness(rows, cols)
    D = np.concatenate([D, np.zeros((len(D), 1))], 1)
    scale2 = float(np.median(m[sel])) ** 2
    weight = np.ones(len(y))
    for _ in range(iters):
        Aw = A * weight[:, None]
        M = A.T @ Aw + smooth * weight.sum() * scale2 * (D.T @ D)
        x = np.linalg.solve(M + 1e-12 * np.eye(n + 1), Aw.T @ y)
        r = A @ x - y
        spread = 2.0 * 1.4826 * float(np.median(np.abs(r))) + 1e-12
        weight = np.minimum(1.0, spread / np.maximum(np.abs(r), 1e-12))
    s = (wts * x[:n][idx]).sum(1)
    aligned = (s * m + x[n]).reshape(h, w)
    valid = np.isfinite(aligned) & (aligned > 0)
    if valid.sum() < 0.5 * np.isfinite(mono).sum():
        return None
    return np.where(valid, aligned, np.nan).astype(np.float32)


def fuse_depth(metric: np.ndarray, aligned: np.ndarray, max_rel: float = 0.1, spread_k: float = 0.0) -> np.ndarray:
    """(H, W) metric depth (0 where unknown) with its holes filled from `aligned` (H, W; NaN
    stays unknown), and its pixels more than a share `r` of `aligned` away from it replaced by
    it: there the stereo is most likely one of its gross errors (a window across a depth edge,
    a repeated texture) rather than the fit off by that much (`StereoConfig.mono_max_rel` has
    the measurements). r = max(`max_rel`, `spread_k` robust spreads (1.4826 x the median) of the
    known pixels' |metric / aligned - 1|): a fit that is itself far from the stereo (a prior whose
    errors vary faster than the fit's nodes) does not veto good stereo.
    max_rel <= 0 keeps every known metric pixel."""
    known = metric > 0
    both = known & np.isfinite(aligned) & (aligned > 0)
    r = max_rel
    if max_rel > 0 and spread_k > 0 and both.any():
        r = max(r, spread_k * 1.4826 * float(np.median(np.abs(metric[both] / aligned[both] - 1.0))))
    agree = known & ((np.abs(metric - aligned) <= r * aligned) | (max_rel <= 0))
    keep = agree | (known & ~np.isfinite(aligned))
    return np.where(keep, metric, aligned).astype(np.float32)
