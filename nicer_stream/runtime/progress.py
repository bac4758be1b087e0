"""Progress lines on stderr for long work."""
from __future__ import annotations

import sys
import time
from typing import Callable


class Progress:
    """Prints `label i/n loss ... eta` on the first call (after the first iteration), then
    at most every `every_s` seconds, and at the end."""

    def __init__(self, label: str, every_s: float = 5.0, stream=None,
                 clock: Callable[[], float] = time.perf_counter) -> None:
        self.label, self.every_s, self.clock = label, every_s, clock
        self.stream = sys.stderr if stream is None else stream  # looked up now: pytest swaps sys.stderr
        self.t0 = clock()
        self.last = -1e9

    def __call__(self, i: int, n: int, loss: float | None = None) -> None:
        now = self.clock()
        done = i + 1 >= n
        if now - self.last < self.every_s and not done:
            return
        self.last = now
        el = now - self.t0
        eta = el / (i + 1) * (n - i - 1)
        msg = f"{self.label} {i + 1}/{n}" + (f" loss {loss:.4f}" if loss is not None else "") + f" {el:.0f}s eta {eta:.0f}s"
        print(msg, file=self.stream, flush=True)
