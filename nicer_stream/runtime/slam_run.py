"""`nicer-stream run`: `run_slam` runs a `RunSession` (runtime/session.py) under the stop signals;
`RunRequest` and `RunOutcome` (runtime/run_request.py) are what it takes and gives."""
from __future__ import annotations

from nicer_stream.runtime.run_request import RunOutcome, RunRequest
from nicer_stream.runtime.session import RunSession
from nicer_stream.runtime.stop import StopSignals

__all__ = ["RunOutcome", "RunRequest", "run_slam"]


def run_slam(req: RunRequest) -> RunOutcome:
    """Run SLAM over the source and write the output directory. A stop (Ctrl-C, SIGTERM) or an
    error inside a stage ends the loop early; every output computed so far is still written."""
    with StopSignals() as stop:
        return RunSession(req, stop).run()
