"""Progress for long work: lines on stderr for loops of known length (`Progress`), and the
per-frame status of a run against the log's length (`frame_status`)."""
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


def duration(seconds: float) -> str:
    """'42 s', '4 min 50 s', '2 h 05 min': an ETA a person reads at a glance."""
    s = max(int(round(seconds)), 0)
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


def frame_status(done: int, total: int | None, elapsed_s: float) -> str:
    """'120/723, 17%, 2.10 frames/s, eta 4 min 50 s' for `done` of `total` frames after
    `elapsed_s` seconds; '120 done, 2.10 frames/s' when the source does not know its length.
    The ETA is '?' until a frame is done (the two-view start holds the first ones)."""
    rate = done / max(elapsed_s, 1e-9)
    if total is None:
        return f"{done} done, {rate:.2f} frames/s"
    eta = duration(max(total - done, 0) / rate) if done else "?"
    pct = 100.0 * done / total if total else 100.0
    return f"{done}/{total}, {pct:.0f}%, {rate:.2f} frames/s, eta {eta}"
