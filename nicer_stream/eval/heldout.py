"""Held-out views: frames no mapping call fitted the map to (not keyframes, never a mapping
call's frame), rendered from the run's saved scene at their tracked poses (eval/evaluate.py compares them
with the source's images and depth as it does the mapped views): novel-view synthesis as the paper reports it, on views SLAM
tracked but never mapped.

LPIPS is not computed: it needs the `lpips` package and its AlexNet weights, which this
project does not depend on; `lpips` stays null and the report's `note` says so.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Callable

import numpy as np
import torch

from nicer_stream.io.scene_file import load_scene
from nicer_stream.render.renderer import RenderedImage, render_image
from nicer_stream.types import Frame, Intrinsics
from sources.base import SourceOptions, resize_frame


class HeldOutPicker:
    """Chooses up to `n` evenly spread held-out frames while the source is iterated once:
    frames with a tracked pose (matched by timestamp) that are not in `mapped`."""

    def __init__(self, est_t: np.ndarray, est_T: np.ndarray, mapped: set[int], n: int, tol: float = 5e-4) -> None:
        self.est_t, self.est_T, self.mapped, self.n, self.tol = est_t, est_T, mapped, n, tol
        unmapped = max(len(est_t) - len(mapped), 1)
        self.stride = max(1, math.ceil(unmapped / max(n, 1)))
        self.seen = 0
        self.picked: list[tuple[Frame, np.ndarray]] = []

    def offer(self, frame: Frame) -> None:
        if frame.index in self.mapped or len(self.picked) >= self.n or not len(self.est_t):
            return
        k = int(np.abs(self.est_t - frame.timestamp).argmin())
        if abs(self.est_t[k] - frame.timestamp) > self.tol:
            return
        if self.seen % self.stride == self.stride // 2:
            self.picked.append((frame, self.est_T[k]))
        self.seen += 1


def render_heldout(scene_path: Path, picked: list[tuple[Frame, np.ndarray]], intr: Intrinsics,
                   progress: Callable[[str], None] | None = None) -> list[tuple[Frame, RenderedImage]]:
    """Each picked frame resized to the run's intrinsics `intr`, with the render of its tracked
    pose (estimate world) from the saved scene; frames of another aspect are left out.
    `progress` gets a line before each render."""
    if not picked:
        return []
    cfg, model, beta = load_scene(scene_path)
    out = []
    for k, (frame, T) in enumerate(picked):
        f = resize_frame(frame, SourceOptions(max_side=max(intr.width, intr.height)))
        if (f.width, f.height) == (intr.width, intr.height):
            if progress is not None:
                progress(f"held-out view {k + 1}/{len(picked)} (frame {frame.index}): rendering")
            out.append((f, render_image(model, beta, torch.as_tensor(T, dtype=torch.float32), intr, cfg.render)))
    return out
