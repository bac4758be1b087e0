"""The mapping worker: runs SlamSystem's mapping jobs on a thread of their own, one at a time,
while the caller tracks the next frames against the last published map snapshot.

Threads, not processes: a job and tracking share the keyframes, priors and the map (a process
would pickle ~90 MB of map per call at `fast` sizes), and torch releases the GIL inside its
ops. torch's intra-op thread count is per thread here (OpenMP's is a per-thread setting), so
the two stages split the cores between them (`split_threads`).
"""
from __future__ import annotations

import os
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Callable

import torch

from nicer_stream.slam.map_jobs import MapJob, MapResult


def available_cores() -> int:
    """The cores this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def split_threads(total: int | None = None) -> tuple[int, int]:
    """(tracking, mapping) intra-op threads for `total` cores (default: `available_cores`)."""
    total = available_cores() if total is None else total
    mapping = max(1, (total + 1) // 2)
    return max(1, total - mapping), mapping


class MappingThread:
    """A `MappingExecutor` (slam/map_jobs.py) with one worker thread and one job in flight."""

    background = True

    def __init__(self, threads: int, threads_alone: int | None = None) -> None:
        self.threads = threads
        self.threads_alone = threads_alone or threads  # for a closing job: the caller only waits
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="mapping")
        self._future: Future | None = None

    def submit(self, job: MapJob, run: Callable[[MapJob], MapResult]) -> None:
        if self._future is not None:
            raise RuntimeError("MappingThread.submit: a job is still in flight (poll or drain first)")
        self._future = self._pool.submit(self._call, run, job)

    def _call(self, run: Callable[[MapJob], MapResult], job: MapJob) -> MapResult:
        torch.set_num_threads(self.threads_alone if job.closing else self.threads)  # this thread's own
        return run(job)

    def busy(self) -> bool:
        """A job is in flight or its result is not collected yet."""
        return self._future is not None

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the job in hand has finished (not collected: `poll` hands it over); False on timeout."""
        if self._future is None:
            return True
        try:
            self._future.exception(timeout)
        except TimeoutError:
            return False
        return True

    def poll(self) -> list[MapResult]:
        if self._future is None or not self._future.done():
            return []
        return self.drain()

    def drain(self) -> list[MapResult]:
        if self._future is None:
            return []
        future, self._future = self._future, None
        return [future.result()]  # re-raises the job's exception in the caller's thread

    def close(self) -> None:
        """Wait for the job in hand (a stop request ends it within an iteration) and the thread."""
        self._pool.shutdown(wait=True)

