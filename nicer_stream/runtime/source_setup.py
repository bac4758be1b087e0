"""Opening a source with the preset's image size unless the user chose one."""
from __future__ import annotations

from dataclasses import replace

from nicer_stream.config import SlamConfig
from sources import open_source
from sources.base import FrameSource, SourceOptions


def open_configured(uri: str, opts: SourceOptions, cfg: SlamConfig,
                    tracking: bool = True) -> tuple[FrameSource, SourceOptions]:
    """The source at the preset's `max_side` when neither --max-side nor --scale was given, with
    the frontend's larger grey copy (`frontend.max_side`) when the run tracks (`tracking`; not
    `map`, which has known poses) with a frontend; returns the options actually used
    (evaluation must read frames the same way)."""
    if opts.max_side is None and opts.scale is None and cfg.max_side is not None:
        opts = replace(opts, max_side=cfg.max_side)
    if (tracking and opts.detail_side is None and cfg.frontend.max_side is not None
            and cfg.tracking.frontend != "none"):
        opts = replace(opts, detail_side=cfg.frontend.max_side)
    return open_source(uri, opts), opts

