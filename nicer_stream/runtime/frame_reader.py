"""The source reader: frames are read and decoded on a thread of their own, a few ahead of
SLAM, through a bounded queue. Offline sources never drop a frame here (the reader waits for
room); `--realtime` drops at the consumer (runtime/pacer.py)."""
from __future__ import annotations

import queue
import threading
from typing import Iterable, Iterator, TypeVar

T = TypeVar("T")

_END = object()


class ReadAhead:
    """Iterates `source` on a worker thread, at most `depth` items ahead of the consumer.
    An exception in the source is raised in the consumer at that item; `close()` (or leaving a
    `with` block) stops the reader."""

    def __init__(self, source: Iterable[T], depth: int = 4) -> None:
        self._queue: queue.Queue = queue.Queue(depth)
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._read, args=(source,), name="reader", daemon=True)
        self._thread.start()

    @property
    def depth(self) -> int:
        """Items read and waiting for the consumer (for the status line)."""
        return self._queue.qsize()

    def _put(self, item) -> bool:
        while not self._closed.is_set():
            try:
                self._queue.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def _read(self, source: Iterable[T]) -> None:
        try:
            for item in source:
                if not self._put(item):
                    return
        except BaseException as e:  # handed to the consumer
            self._put(e)
            return
        self._put(_END)

    def __iter__(self) -> Iterator[T]:
        while True:
            item = self._queue.get()
            if item is _END:
                return
            if isinstance(item, BaseException):
                raise item
            yield item

    def close(self) -> None:
        self._closed.set()
        self._thread.join(timeout=5)

    def __enter__(self) -> "ReadAhead":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
