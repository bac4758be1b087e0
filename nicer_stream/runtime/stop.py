"""Ctrl-C and SIGTERM as a stop request: the run finishes the work in hand and writes its outputs.

The first SIGINT or SIGTERM only sets a flag that the run loop and the mapping iterations
poll (so a stop takes at most one tracking step or mapping iteration, plus writing); a second
one exits at once with the conventional code (128 + signal: 130 for SIGINT, 143 for SIGTERM).
"""
from __future__ import annotations

import os
import signal
import sys
import threading

_NAMES = {signal.SIGINT: "Ctrl-C (SIGINT)", signal.SIGTERM: "SIGTERM"}


class StopSignals:
    """Context manager: installs the handlers in the main thread and restores the old ones."""

    def __init__(self) -> None:
        self.signum: int | None = None
        self._old: dict[int, object] = {}

    def __enter__(self) -> "StopSignals":
        if threading.current_thread() is threading.main_thread():
            for s in _NAMES:
                self._old[s] = signal.signal(s, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        for s, old in self._old.items():
            signal.signal(s, old)
        self._old.clear()

    def _handle(self, signum: int, frame) -> None:
        if self.signum is not None:
            os._exit(128 + signum)  # the second stop: at once, as asked
        self.signum = signum
        print(f"\n{_NAMES[signum]}: stopping, writing what was computed so far "
              f"(send it again to quit at once)", file=sys.stderr, flush=True)

    def request(self, signum: int = signal.SIGINT) -> None:
        """Record a stop without a signal (a KeyboardInterrupt the handlers did not catch)."""
        if self.signum is None:
            self.signum = signum

    @property
    def requested(self) -> bool:
        return self.signum is not None

    @property
    def exit_code(self) -> int:
        """130 after SIGINT, 143 after SIGTERM, 0 without a stop."""
        return 128 + self.signum if self.signum is not None else 0

    @property
    def reason(self) -> str | None:
        return _NAMES.get(self.signum) if self.signum is not None else None
