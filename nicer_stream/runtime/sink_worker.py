"""Sinks on a thread of their own: SLAM queues each call and goes on; the worker makes them in
order. Slow logging (Rerun encoding, MCAP compression, live map renders) then never stalls
tracking; the queue is bounded, so a sink that cannot keep up slows the run instead of growing
memory without limit.
"""
from __future__ import annotations

import logging
import queue
import threading
import time
from typing import Callable, Mapping

import torch

from sinks.base import ForwardingSink, Sink

log = logging.getLogger(__name__)

_STOP = object()


class SinkWorker(ForwardingSink):
    """A `Sink` that forwards every call to `sink` on a worker thread (arrays passed in must not
    be modified afterwards: every caller here passes fresh ones). `submit(fn)` queues other work
    that ends in sink calls (live map renders). A failing call is logged once and the sink is
    not called again; `close()` drains the queue, closes `sink` and re-raises that error."""

    def __init__(self, sink: Sink, maxsize: int = 256, threads: int = 1) -> None:
        self.sink, self.threads = sink, threads
        self.seconds = 0.0  # the worker's time in sink calls
        self.error: Exception | None = None
        self._queue: queue.Queue = queue.Queue(maxsize)
        self._closed = False
        # torch.set_num_threads on a new thread also changes the count that threads not yet
        # initialised by torch take up, the caller included (a run with a sink then mapped on one
        # core of two: the demo 2x slower). So the worker sets its own count first, then the
        # caller sets its count again.
        caller_threads = torch.get_num_threads()
        started = threading.Event()
        self._thread = threading.Thread(target=self._loop, args=(started,), name="sinks", daemon=True)
        self._thread.start()
        started.wait()
        torch.set_num_threads(caller_threads)

    @property
    def pending(self) -> int:
        """Calls queued and not made yet."""
        return self._queue.qsize()

    def submit(self, fn: Callable[[], None]) -> None:
        if not self._closed:
            self._queue.put(fn)

    def _loop(self, started: threading.Event) -> None:
        torch.set_num_threads(self.threads)
        started.set()
        while (fn := self._queue.get()) is not _STOP:
            if self.error is not None:
                continue  # drain: the sink failed
            t0 = time.perf_counter()
            try:
                fn()
            except Exception as e:  # reported at close(); the run goes on without this sink
                self.error = e
                log.warning("sink call failed, no further sink output: %s: %s", type(e).__name__, e)
            self.seconds += time.perf_counter() - t0

    def _forward(self, name: str, *args, **kwargs) -> None:
        method = getattr(self.sink, name)
        self.submit(lambda: method(*args, **kwargs))

    def log_scalars(self, index: int, values: Mapping[str, float]) -> None:
        super().log_scalars(index, dict(values))  # the caller's dict may change before the worker gets to it

    def wants_image(self, index: int) -> bool:
        return self.sink.wants_image(index)

    def log_frame(self, index, timestamp, rgb, intrinsics, T_world_cam, depth=None, normal=None,
                  gt_T_world_cam=None, timestamp_ns=None) -> None:
        """A frame whose image the sink would not record is queued as its pose alone: the queue
        then holds no image for it (256 queued full images are hundreds of MB)."""
        if self.sink.wants_image(index):
            self._forward("log_frame", index, timestamp, rgb, intrinsics, T_world_cam, depth=depth, normal=normal,
                          gt_T_world_cam=gt_T_world_cam, timestamp_ns=timestamp_ns)
        else:
            self._forward("log_pose", index, timestamp, T_world_cam, gt_T_world_cam=gt_T_world_cam,
                          timestamp_ns=timestamp_ns)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._queue.put(_STOP)
            self._thread.join()
        self.sink.close()
        if self.error is not None:
            err, self.error = self.error, None
            raise err
