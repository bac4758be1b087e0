"""--realtime: play a recorded log at its recorded rate."""
from __future__ import annotations

import time


class Pacer:
    """--realtime: drop frames whose recorded time has already passed on the wall clock."""

    def __init__(self, enabled: bool) -> None:
        self.enabled, self.t0, self.s0, self.dropped = enabled, None, None, 0

    def drop(self, timestamp: float) -> bool:
        if not self.enabled:
            return False
        now = time.perf_counter()
        if self.t0 is None:
            self.t0, self.s0 = now, timestamp
            return False
        due = self.t0 + (timestamp - self.s0)
        if now > due:
            self.dropped += 1
            return True
        time.sleep(max(0.0, due - now))
        return False
