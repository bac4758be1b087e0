"""`RunState`: what a run holds while it goes (typed), which `RunSession` fills and the summary
and the final outputs read."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from nicer_stream.config import SlamConfig
    from nicer_stream.priors import PriorEngine
    from nicer_stream.runtime.frame_book import FrameBook
    from nicer_stream.runtime.live_outputs import LiveMapOutputs
    from nicer_stream.runtime.pacer import Pacer
    from nicer_stream.runtime.run_request import RunRequest
    from nicer_stream.runtime.stage_timer import StageTimer
    from nicer_stream.runtime.stop import StopSignals
    from nicer_stream.runtime.thread_plan import ThreadPlan
    from nicer_stream.slam.system import SlamSystem
    from sinks.base import Sink
    from sources.base import FrameSource


class RunState:
    """The parts of a run and how it stands."""

    req: RunRequest
    """What the run was asked to do."""
    stop: StopSignals
    """Ctrl-C / SIGTERM, as requested so far."""
    cfg: SlamConfig
    """The preset with the config file's overrides."""
    timer: StageTimer
    """Seconds per stage (priors, tracking, mapping, frontend, sinks)."""
    threads: ThreadPlan
    """Intra-op threads and where mapping runs."""
    source: FrameSource
    """The frame source."""
    out: Path
    """The output directory."""
    engine: PriorEngine
    """The depth / normal and flow providers."""
    slam: SlamSystem
    """The SLAM system."""
    sink: Sink | None
    """The sink (a SinkWorker unless --sync), or None."""
    live: LiveMapOutputs | None
    """Live renders and meshes of map updates to the sink, or None."""
    pacer: Pacer
    """--realtime's frame dropping."""
    book: FrameBook
    """The frames read, held and reported, the images kept for the final renders."""
    error: str | None
    """The one-line error that ended the run early, if one did."""
    early: bool
    """Stopped or failed: no final renders; summary.json says interrupted."""

    def say(self, text: str) -> None:
        """A progress line, unless --quiet."""
        if not self.req.quiet:
            print(text, flush=True)
