"""Sink spec queries: `run`'s --log-images-every / --log-image-side reach every spec that has no
query of its own, and the spec's query becomes the sink's options."""
from pathlib import Path

import pytest

from nicer_stream.cli.sink_specs import resolve_sinks as _resolve_sinks
from nicer_stream.errors import UserError
from sinks.options import SinkOptions, split_spec


def test_run_adds_the_image_stride_and_size_to_specs_without_a_query(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    specs = _resolve_sinks(["rerun:a.rrd", "mcap:b.mcap,rerun:c.rrd", "rerun:d.rrd?images_every=1"], Path("out"), 10, 320)
    assert specs == ("rerun:a.rrd?images_every=10&image_side=320",
                     "mcap:b.mcap?images_every=10&image_side=320,rerun:c.rrd?images_every=10&image_side=320",
                     "rerun:d.rrd?images_every=1")  # the user's own query wins
    assert [split_spec(s.split(",")[0]) for s in specs[:1]] == [("rerun:a.rrd", SinkOptions(10, 320))]
    assert _resolve_sinks(["mcap:b.mcap"], Path("out"), 1, 0) == ("mcap:b.mcap",)  # everything, as read
    headless = _resolve_sinks(["rerun"], Path("out"), 5, 0)[0]
    assert headless == f"rerun:{Path('out') / 'recording.rrd'}?images_every=5"
    with pytest.raises(UserError, match="--log-images-every"):
        _resolve_sinks(["mcap:b.mcap"], Path("out"), 0, 320)
