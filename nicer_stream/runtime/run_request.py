"""What `nicer-stream run` is asked (`RunRequest`) and how a run ended (`RunOutcome`)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from sources.base import SourceOptions


@dataclass(frozen=True)
class RunRequest:
    """What `nicer-stream run` was asked to do."""

    source: str
    """Source URI (`sources.open_source`)."""
    out_dir: Path
    """Output directory (created)."""
    priors: str = "auto"
    """Depth / normal prior provider by name (`priors.make_depth_normal_provider`)."""
    flow: str | None = None
    """Flow prior provider by name (None: the depth provider's default)."""
    preset: str = "fast"
    """Config preset: fast or paper."""
    config_file: str | None = None
    """A .toml / .json file overriding preset fields."""
    sinks: tuple[str, ...] = ()
    """Sink specs (`sinks.make_sink`)."""
    device: str = "cpu"
    """torch device."""
    realtime: bool = False
    """Play the log at its recorded rate, dropping frames the SLAM cannot keep up with."""
    render_every: int = 10
    """Render (and evaluate) every N-th frame at the end, and the last one."""
    max_renders: int = 20
    """At most this many of those (0: no cap): on longer logs the stride doubles until they fit
    (`runtime/render_picker.py`), so the end of a run does not grow with its length."""
    quiet: bool = False
    """No per-frame lines and no mapping progress: errors and the final summary only."""
    live_mesh_every: int = 5
    """With a sink: a coarse mesh every this many map updates (0: only the final mesh)."""
    sync: bool = False
    """Everything in one thread, in order (deterministic under a seed); default: frames read and
    sinks called on threads of their own, mapping as `mapping_worker` says."""
    mapping_worker: str = "auto"
    """'on': mapping calls on a worker thread, tracking against the last published map; 'off':
    mapping inline with tracking; 'auto': on with a GPU or >= 4 cores (on 2 cores it was slower: docs/runtime.md)."""
    source_opts: SourceOptions = field(default_factory=SourceOptions)
    """Which frames of the source, at what size, with which intrinsics."""


@dataclass(frozen=True)
class RunOutcome:
    """Where the outputs are and how the run ended."""

    out_dir: Path
    """The output directory."""
    exit_code: int = 0
    """0; 130 / 143 after a stop by SIGINT / SIGTERM; 1 after an error inside a stage."""
    error: str | None = None
    """The one-line error that ended the run early (also in summary.json)."""
