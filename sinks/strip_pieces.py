"""A polyline that grows during a run, cut into pieces so that logging it stays linear in its
length: re-logging the whole line every few frames would store O(N^2) points."""
from __future__ import annotations

import numpy as np


class StripPieces:
    """Collects points (3,) and hands back a piece once `every` new ones have come; each piece
    starts at the previous piece's last point, so the pieces join into one line."""

    def __init__(self, every: int) -> None:
        self.every = max(1, int(every))
        self.count = 0  # pieces handed out so far: the next piece's number
        self._points: list[np.ndarray] = []  # the joint, then the points not handed out yet
        self._new = 0

    def add(self, point: np.ndarray) -> np.ndarray | None:
        """Append a point; returns the full piece (K, 3) when `every` points have come, else None."""
        self._points.append(np.asarray(point, dtype=np.float64).reshape(3))
        self._new += 1
        return self.take() if self._new >= self.every else None

    def take(self) -> np.ndarray | None:
        """The piece so far (K, 3), with the previous piece's end first; None when no point is new."""
        if not self._new:
            return None
        piece = np.stack(self._points)
        self.count += 1
        self._points, self._new = self._points[-1:], 0
        return piece
