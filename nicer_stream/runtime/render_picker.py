"""Which frames `nicer-stream run` renders (and evaluates) at the end of a stream.

Every `every`-th frame index, as long as at most `max_views` are kept; beyond that the stride
doubles and every other kept frame is let go, so a long log ends with between `max_views` / 2 and
`max_views` renders spread evenly over it (the runner adds the last frame), and holds no more of
their images until then. The stream's length is not known in advance. Without the cap the end of a
run grew with its length (docs/performance.md).
"""
from __future__ import annotations


class RenderPicker:
    """offer(index) for each tracked frame in order; `every` >= 1; `max_views` 0 = no cap."""

    def __init__(self, every: int, max_views: int = 0):
        if every < 1 or max_views < 0:
            raise ValueError(f"render every {every} frames, at most {max_views} views: need every >= 1, max >= 0")
        self.stride = every
        self.max_views = max_views
        self.kept: list[int] = []

    def offer(self, index: int) -> tuple[bool, list[int]]:
        """(keep frame `index`'s image for a render, the indices kept before and now let go)."""
        if index % self.stride:
            return False, []
        self.kept.append(index)
        released: list[int] = []
        while self.max_views and len(self.kept) > self.max_views:
            self.stride *= 2
            released += [i for i in self.kept if i % self.stride]
            self.kept = [i for i in self.kept if i % self.stride == 0]
        keep = index in self.kept
        return keep, [i for i in released if i != index]
