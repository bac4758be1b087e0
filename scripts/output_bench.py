"""Seconds for the end-of-run outputs of a finished run: one full-resolution render and the
mesh, from OUT/scene.pt and OUT/trajectory.tum (the `sinks` stage of `summary.json`).

Usage: .venv/bin/python scripts/output_bench.py OUT [--repeat N]"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from nicer_stream.io.scene_file import load_scene
from nicer_stream.io.trajectory import read_tum
from nicer_stream.render.renderer import render_image
from nicer_stream.runtime.scene_export import scene_mesh
from nicer_stream.types import Intrinsics


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--repeat", type=int, default=1)
    a = ap.parse_args()
    cfg, model, beta = load_scene(a.out / "scene.pt")
    _, poses = read_tum(a.out / "trajectory.tum")
    intr = Intrinsics(**json.loads((a.out / "summary.json").read_text())["intrinsics"])
    for _ in range(a.repeat):
        t0 = time.perf_counter()
        render_image(model, beta, torch.as_tensor(poses[0], dtype=torch.float32), intr, cfg.render)
        t1 = time.perf_counter()
        mesh = scene_mesh(model, beta, poses, intr, cfg)
        t2 = time.perf_counter()
        print(f"render {intr.width}x{intr.height}: {t1 - t0:.2f} s, mesh {cfg.mesh.resolution}^3: {t2 - t1:.2f} s "
              f"({len(mesh.faces)} faces)", flush=True)


if __name__ == "__main__":
    main()
