"""Output sinks addressed by spec strings, combinable with commas.

  rerun:FILE.rrd       Rerun recording file
  rerun                spawn a Rerun viewer (needs a display)
  rerun+grpc[:URL]     stream to a running viewer (default URL if omitted)
  mcap:FILE.mcap       Foxglove-protobuf MCAP file

Each takes `?images_every=N&image_side=PX` (sinks/options.py): input images of every N-th frame
only, downsized to PX on the longer side. `make_sink("rerun:out/run.rrd,mcap:out/run.mcap")`
returns a MultiSink.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

from nicer_stream.errors import UserError
from sinks.base import ForwardingSink, Sink
from sinks.options import SinkOptions, split_spec

SPECS = ("rerun:FILE.rrd", "rerun", "rerun+grpc:URL", "mcap:FILE.mcap")


class MultiSink(ForwardingSink):
    """Forwards every call to several sinks; closing closes all of them even if one fails."""

    def __init__(self, sinks: Sequence[Sink]) -> None:
        self.sinks = list(sinks)

    def _forward(self, name: str, *args, **kwargs) -> None:
        for s in self.sinks:
            getattr(s, name)(*args, **kwargs)

    def wants_image(self, index: int) -> bool:
        return any(s.wants_image(index) for s in self.sinks)

    def close(self) -> None:
        first: BaseException | None = None
        for s in self.sinks:
            try:
                s.close()
            except Exception as e:  # keep closing the others: their files must still be finalised
                first = first or e
        if first is not None:
            raise first


def _file_target(scheme: str, path: str, suffix: str) -> Path:
    if not path:
        raise UserError(f"sink '{scheme}:' needs a file name, e.g. {scheme}:out/run{suffix}")
    if not path.endswith(suffix):
        raise UserError(f"sink '{scheme}:{path}' must name a {suffix} file, e.g. {scheme}:out/run{suffix}")
    return Path(path)


def _make_one(spec: str) -> Sink:
    base, opts = split_spec(spec.strip())
    scheme, _, rest = base.partition(":")
    if scheme in ("rerun", "rerun+grpc"):
        from sinks.rerun_sink import RerunSink

        if scheme == "rerun+grpc":
            return RerunSink(grpc_url=rest or None, options=opts)
        return RerunSink(spawn=True, options=opts) if not rest else RerunSink(_file_target("rerun", rest, ".rrd"), options=opts)
    if scheme == "mcap":
        from sinks.mcap_sink import McapSink

        return McapSink(_file_target("mcap", rest, ".mcap"), options=opts)
    raise UserError(f"unknown sink '{spec}': use one of {', '.join(SPECS)} (comma-separated for several)")


def make_sink(spec: str | Sequence[str]) -> Sink:
    """Sink for `spec` ('rerun:a.rrd', 'mcap:b.mcap', ...); several specs (list or commas) -> MultiSink."""
    parts = [p for p in (spec.split(",") if isinstance(spec, str) else spec) if p.strip()]
    if not parts:
        raise UserError(f"empty sink spec: use one of {', '.join(SPECS)}")
    sinks: list[Sink] = []
    try:
        for p in parts:
            sinks.append(_make_one(p))
    except BaseException:
        for s in sinks:  # do not leave half-opened files behind
            s.close()
        raise
    return sinks[0] if len(sinks) == 1 else MultiSink(sinks)


__all__ = ["Sink", "MultiSink", "SinkOptions", "make_sink", "SPECS"]
