"""Computes each frame's priors as it streams in (before the SLAM system sees it).

This is the one place besides evaluation and sinks that holds frames with ground
truth: the `oracle` provider needs it. Flows are computed between the new frame
and the latest keyframes, in both directions (the mapper's warping partners), and from
the previous frame to the new one (the tracker's flow initialisation).
"""
from __future__ import annotations

from nicer_stream.priors import PriorEngine
from nicer_stream.types import Frame, Priors


class PriorStage:
    def __init__(self, engine: PriorEngine, keyframes_kept: int = 2) -> None:
        self.engine = engine
        self.keep = keyframes_kept
        self.keyframes: list[Frame] = []
        self.previous: Frame | None = None

    def __call__(self, frame: Frame) -> Priors:
        pri = self.engine.priors(frame, self.keyframes)
        sources = list(self.keyframes)
        if self.previous is not None and all(kf.index != self.previous.index for kf in sources):
            sources.append(self.previous)
        for src in sources:
            back = self.engine.flow(src, frame)
            if back is not None:
                pri.flows.append(back)
        self.previous = frame
        return pri

    def add_keyframe(self, frame: Frame) -> None:
        self.keyframes = (self.keyframes + [frame])[-self.keep:]
