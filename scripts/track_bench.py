"""Tracking optimisers side by side: a map of the first Replica frames fitted with GT poses
(oracle priors: a benchmark of the optimiser, not of the SLAM), then each frame tracked from
its GT pose perturbed by a fixed twist (~1.5 cm, ~0.6 deg: what flow PnP leaves), per variant:
pose error after tracking, iterations and seconds.

Usage: .venv/bin/python scripts/track_bench.py [--map-iters N] [--frames N]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path
from dataclasses import replace

import torch

from nicer_stream import config as config_mod
from nicer_stream.geometry.se3 import invert, rotation_angle, se3_exp
from nicer_stream.mapping.mapper import Mapper
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from nicer_stream.tracking.tracker import Tracker

from iter_bench import load  # noqa: E402 - scripts/ is on sys.path when run as a script

VARIANTS = {
    "adam 60 (fast)": {},
    "adam 20": {"iters": 20},
    "gn 3": {"optimizer": "gauss_newton", "iters": 3},
    "gn 6, mean of last 3": {"optimizer": "gauss_newton", "iters": 6, "average": 3},
    "gn 4, mean of last 2": {"optimizer": "gauss_newton", "iters": 4, "average": 2},
    "gn grey 3": {"optimizer": "gauss_newton", "iters": 3, "residual": "grey"},
    "gn grey 6, mean of last 3": {"optimizer": "gauss_newton", "iters": 6, "average": 3, "residual": "grey"},
    "gn grey 6, mean of last 3, 1024 rays": {"optimizer": "gauss_newton", "iters": 6, "average": 3,
                                              "residual": "grey", "rays": 1024},
}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--map-iters", type=int, default=350)
    ap.add_argument("--frames", type=int, default=8)
    a = ap.parse_args()
    cfg = config_mod.preset("fast")
    mfs, poses, bound = load(a.frames, cfg.max_side)
    torch.manual_seed(0)
    model, beta = SceneModel(cfg.model, bound), BetaField(cfg.render)
    t = time.perf_counter()
    cache = Path(f"/tmp/track_bench_map_{a.frames}_{a.map_iters}.pt")
    if cache.exists():  # the same map as last time (seeded): only the trackers change
        state = torch.load(cache)
        model.load_state_dict(state["model"])
        beta.load_state_dict(state["beta"])
    else:
        Mapper(model, beta, cfg, 0).optimise(mfs[::2], poses, a.map_iters, color_start=cfg.mapping.batch_color_start)
        torch.save({"model": model.state_dict(), "beta": beta.state_dict()}, cache)
    print(f"map of frames {[f.index for f in mfs[::2]]}: {time.perf_counter() - t:.0f} s", flush=True)
    delta = se3_exp(torch.tensor([0.010, -0.008, 0.008, 0.006, -0.005, 0.004]))
    print("| variant | trans err cm (mean) | rot err deg (mean) | iterations | s/frame |\n|---|---|---|---|---|")
    for name, change in VARIANTS.items():
        tr = Tracker(model, beta, replace(cfg.tracking, **change), cfg.render, 0)
        errs, rots, its, secs = [], [], [], []
        for f in mfs[1::2]:
            T_gt = poses[f.index]
            res = tr.track(f, T_gt @ delta)
            d = invert(T_gt) @ res.T_world_cam
            errs.append(float(d[:3, 3].norm()) * 100)
            rots.append(float(rotation_angle(d[:3, :3])) * 57.2958)
            its.append(res.iters)
            secs.append(res.seconds)
        n = len(errs)
        print(f"| {name} | {sum(errs) / n:.2f} | {sum(rots) / n:.3f} | {sum(its) / n:.1f} | {sum(secs) / n:.2f} |", flush=True)
    d = delta
    print(f"start error: {float(d[:3, 3].norm()) * 100:.2f} cm, {float(rotation_angle(d[:3, :3])) * 57.2958:.3f} deg")


if __name__ == "__main__":
    main()
