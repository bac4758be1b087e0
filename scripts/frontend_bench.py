"""The classical frontend alone on a source, with its own poses (no map): what the SLAM's
poses start from. Prints ATE (Sim(3)) against the source's ground truth, the per-window Sim(3)
scale (a collapsing scale shows as a falling ratio), the longest run of frames that barely move
(a freeze) and the frontend's health reports, then the frames per second.

Usage: .venv/bin/python scripts/frontend_bench.py SOURCE_URI [--max-frames N] [--stride S]
       [--window W] [--set frontend.key=value ...]
"""
from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from nicer_stream.config import FrontendConfig
from nicer_stream.eval.trajectory import ate, umeyama
from nicer_stream.frontend.odometry import FrontendOdometry
from sources import open_source
from sources.base import SourceOptions


def window_scales(est: np.ndarray, gt: np.ndarray, window: int) -> list[tuple[int, float]]:
    """(first frame, Sim(3) scale gt-from-est) of consecutive windows of camera centres."""
    out = []
    for a in range(0, len(est) - window + 1, window):
        sl = slice(a, a + window)
        if np.linalg.norm(np.ptp(gt[sl, :3, 3], axis=0)) < 1e-3:
            continue
        out.append((a, umeyama(est[sl, :3, 3], gt[sl, :3, 3]).scale))
    return out


def longest_still(est: np.ndarray, gt: np.ndarray, eps_frac: float = 0.05) -> int:
    """Longest run of frames whose estimated step is below `eps_frac` of the GT step (after
    Sim(3) alignment) while the GT moved at least 2 mm: a frozen estimate."""
    sim = umeyama(est[:, :3, 3], gt[:, :3, 3])
    c = sim.apply_points(est[:, :3, 3])
    d_est = np.linalg.norm(np.diff(c, axis=0), axis=1)
    d_gt = np.linalg.norm(np.diff(gt[:, :3, 3], axis=0), axis=1)
    still = (d_gt > 2e-3) & (d_est < eps_frac * d_gt)
    best = run = 0
    for s in still:
        run = run + 1 if s else 0
        best = max(best, run)
    return best


def parse_set(items: list[str]) -> dict:
    out = {}
    for it in items:
        k, v = it.split("=", 1)
        k = k.removeprefix("frontend.")
        cur = getattr(FrontendConfig(), k)
        out[k] = type(cur)(float(v)) if isinstance(cur, (int, float)) and not isinstance(cur, bool) else (
            v.lower() in ("1", "true") if isinstance(cur, bool) else v)
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("source")
    ap.add_argument("--max-frames", type=int)
    ap.add_argument("--stride", type=int, default=1)
    ap.add_argument("--window", type=int, default=100, help="frames per scale window")
    ap.add_argument("--set", nargs="*", default=[])
    a = ap.parse_args()
    cfg = replace(FrontendConfig(), **parse_set(a.set))
    src = open_source(a.source, SourceOptions(max_frames=a.max_frames, stride=a.stride, max_side=cfg.max_side))
    odo = FrontendOdometry(cfg)
    t0 = time.perf_counter()
    gts, idx = {}, []
    for n, frame in enumerate(src):
        gts[frame.index] = frame.gt_pose
        idx.append(frame.index)
        odo.step(frame.index, frame.rgb, frame.intrinsics)
        if n % 50 == 0:
            print(f"frame {n}: {odo.frontend.status_line()}", flush=True)
    odo.finish()
    dt = time.perf_counter() - t0
    posed = [i for i in idx if i in odo.poses and gts[i] is not None]
    est = np.stack([odo.poses[i] for i in posed])
    gt = np.stack([gts[i] for i in posed])
    res = ate(est, gt)
    print(f"\nframes {len(idx)}, posed {len(posed)}, {len(idx) / dt:.2f} frames/s")
    print(f"ATE Sim(3) {100 * res.rmse_m:.2f} cm over a {np.linalg.norm(np.diff(gt[:, :3, 3], axis=0), axis=1).sum():.2f} m path")
    scales = window_scales(est, gt, a.window)
    print("per-window scale: " + " ".join(f"{k}:{s:.3f}" for k, s in scales))
    if scales:
        s = np.array([s for _, s in scales])
        print(f"scale spread max/min {s.max() / s.min():.3f}")
    print(f"longest frozen run: {longest_still(est, gt)} frames")
    print(f"health reports: {len(odo.reports)}")
    for r in odo.reports[:20]:
        print("  ", r)


if __name__ == "__main__":
    main()
