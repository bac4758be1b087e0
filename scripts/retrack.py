"""Re-track every frame of a finished run against its final map (OUT/scene.pt), each from its
estimated pose, and write a copy of OUT with that trajectory (a diagnostic: does the online
trajectory agree with the final map? Compare `nicer-stream eval` of both).

`--frames 1,2,...` re-tracks only those frames (the others keep their pose); `--rays` and
`--lr-decay` override the run's tracking settings (docs/performance.md, stops 41-42).

Usage: .venv/bin/python scripts/retrack.py OUT NEW_OUT --source URI [--iters 40] [--optimizer adam]
       [--rays N] [--lr-decay D] [--frames I,J,...]"""
from __future__ import annotations

import argparse
import shutil
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from nicer_stream.io.scene_file import load_scene
from nicer_stream.io.trajectory import read_tum, write_tum
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.tracking.tracker import Tracker
from sources import open_source
from sources.base import SourceOptions


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("new_out", type=Path)
    ap.add_argument("--source", required=True)
    ap.add_argument("--iters", type=int, default=40)
    ap.add_argument("--optimizer", default="adam")
    ap.add_argument("--rays", type=int, default=None, help="pixels per iteration (default: the run's)")
    ap.add_argument("--lr-decay", type=float, default=1.0, help="Adam's rate falls to lr * this at the last step")
    ap.add_argument("--frames", default="", help="comma-separated frame indices (default: every frame)")
    a = ap.parse_args()
    only = {int(x) for x in a.frames.split(",") if x.strip()}
    shutil.copytree(a.out, a.new_out, dirs_exist_ok=True)
    (a.new_out / "eval.json").unlink(missing_ok=True)  # the copy's trajectory is about to change
    cfg, model, beta = load_scene(a.out / "scene.pt")
    stamps, poses = read_tum(a.out / "trajectory.tum")
    tracker = Tracker(model, beta, replace(cfg.tracking, iters=a.iters, keep="last", optimizer=a.optimizer,
                                              lr_decay=a.lr_decay, rays=a.rays or cfg.tracking.rays), cfg.render)
    by_stamp = {round(float(t), 6): i for i, t in enumerate(stamps)}
    new = poses.copy()
    t0 = time.perf_counter()
    for f in open_source(a.source, SourceOptions(max_side=cfg.max_side)):
        i = by_stamp.get(round(float(f.timestamp), 6))
        if i is None or (only and f.index not in only):
            continue
        mf = MapFrame.from_frame(f.without_ground_truth(), None, torch.device("cpu"))
        new[i] = tracker.track(mf, torch.as_tensor(poses[i], dtype=torch.float32)).T_world_cam.double().numpy()
        moved = np.linalg.norm(new[i][:3, 3] - poses[i][:3, 3])
        print(f"frame {f.index}: moved {moved:.4f} (map units)", flush=True)
    write_tum(a.new_out / "trajectory.tum", stamps, new)
    print(f"{len(only) if only else len(stamps)} poses re-tracked in {time.perf_counter() - t0:.0f} s -> {a.new_out}")


if __name__ == "__main__":
    main()
