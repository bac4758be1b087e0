"""Wall-clock accounting per stage (tracking, mapping, priors, sinks) and peak memory."""
from __future__ import annotations

import resource
import sys
import time
from contextlib import contextmanager

from nicer_stream.io.output_dir import StageSeconds


class StageTimer:
    """Accumulates seconds per named stage; `total()` is wall time since creation."""

    def __init__(self) -> None:
        self.start = time.perf_counter()
        self.seconds = StageSeconds()

    @contextmanager
    def stage(self, name: str):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            setattr(self.seconds, name, getattr(self.seconds, name) + time.perf_counter() - t0)

    def total(self) -> float:
        return time.perf_counter() - self.start


def peak_rss_mb() -> float:
    """Peak resident set size of this process in MB."""
    r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return r / 1024 / 1024 if sys.platform == "darwin" else r / 1024
