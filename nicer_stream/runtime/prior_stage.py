"""Computes each frame's priors as it streams in (before the SLAM system sees it).

This is the one place besides evaluation and sinks that holds frames with ground
truth: the `oracle` provider needs it. Flows are computed between the new frame
and the latest keyframes, in both directions (the mapper's warping partners), and from
the previous frame to the new one (the tracker's flow initialisation): with the frame's
priors, or later, on request, for the latest frame only (`deferred_flows`): the SLAM asks for
them when the frame becomes a keyframe or needs its flows, and most frames never do.
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
        # The latest frame, the keyframes it came after and the frames its back flows start at.
        self._latest: tuple[Frame, list[Frame], list[Frame]] | None = None

    def __call__(self, frame: Frame, flows: bool = True) -> Priors:
        """Depth/normal of `frame`, and (with `flows`) its flows; without, `deferred_flows`
        gives the same flows until the next frame comes."""
        sources = list(self.keyframes)
        if self.previous is not None and all(kf.index != self.previous.index for kf in sources):
            sources.append(self.previous)
        self._latest = (frame, list(self.keyframes), sources)
        self.previous = frame
        pri = self.engine.priors(frame, self.keyframes if flows else [])
        if flows:
            pri.flows += self._back_flows()
        return pri

    def deferred_flows(self) -> Priors:
        """The latest frame's flows, as `__call__(frame, flows=True)` would have given them (no
        depth or normal)."""
        frame, keyframes, _ = self._latest
        fw = self.engine.flows((frame, o) for o in keyframes)
        return Priors(frame_index=frame.index, provider=self.engine.label, flows=fw + self._back_flows())

    def _back_flows(self) -> list:
        frame, _, sources = self._latest
        return self.engine.flows((src, frame) for src in sources)

    def add_keyframe(self, frame: Frame) -> None:
        self.keyframes = (self.keyframes + [frame])[-self.keep:]
