"""What a run remembers of its frames between reading them and writing the outputs."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from nicer_stream.runtime.render_picker import RenderPicker
from nicer_stream.types import Frame, Intrinsics


@dataclass
class FrameBook:
    """The frames read, held and reported, the images kept for the final renders, pose latencies."""

    picker: RenderPicker
    """Which frames' images are kept for the final renders."""
    fed: int = 0
    """Frames given to the SLAM."""
    reported: int = 0
    """Frames whose pose was reported."""
    intr: Intrinsics | None = None
    """The intrinsics of the last frame read."""
    kept: dict[int, np.ndarray | None] = field(default_factory=dict)
    """Frame index -> its image for a final render (None: not rendered)."""
    last: tuple[int, np.ndarray] | None = None
    """The last reported frame's index and image (always rendered after a complete run)."""
    waiting: dict[int, Frame] = field(default_factory=dict)
    """Frames fed whose pose event has not come (the two-view start holds frames)."""
    read_at: dict[int, tuple[float, bool]] = field(default_factory=dict)
    """Frame index -> (when the source gave it, whether a map existed then)."""
    latency: list[tuple[float, bool]] = field(default_factory=list)
    """(seconds from a frame's read to its pose event, read after the start-up)."""

    def read(self, frame: Frame, map_exists: bool) -> None:
        """A frame came from the source."""
        self.read_at[frame.index] = (time.perf_counter(), map_exists)
        self.intr = frame.intrinsics

    def fed_to_slam(self, frame: Frame) -> None:
        """The SLAM stepped over `frame`: it waits for its pose event."""
        self.fed += 1
        self.waiting[frame.index] = frame

    def pose_reported(self, index: int, frame: Frame) -> None:
        """The first pose event of `frame`: its latency, whether its image is kept, the last frame."""
        if index in self.read_at:
            t_read, steady = self.read_at.pop(index)
            self.latency.append((time.perf_counter() - t_read, steady))
        keep, released = self.picker.offer(index)
        self.kept[index] = frame.rgb if keep else None
        for i in released:  # a long log: the stride doubled, their images go
            self.kept[i] = None
        self.last = (index, frame.rgb)
        self.reported += 1

    def keep_last(self) -> None:
        """The last frame is always rendered after a complete run, as in `map`."""
        if self.last is not None:
            self.kept[self.last[0]] = self.last[1]

    def renders(self) -> int:
        """Frames whose image is kept for a final render."""
        return sum(v is not None for v in self.kept.values())

    def latency_percentiles(self) -> tuple[list[float], list[float]]:
        """[median, p95] of the pose latency, over all frames and after the start-up (two-view
        hold, first mapping); NaN where there is none."""
        def pct(xs):
            return [float(v) for v in np.percentile(xs, [50, 95])] if xs else [float("nan")] * 2
        return pct([x for x, _ in self.latency]), pct([x for x, ok in self.latency if ok])
