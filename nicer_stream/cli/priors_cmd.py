"""`nicer-stream priors`: precompute a prior cache (format: nicer_stream/priors/cache.py)."""
from __future__ import annotations

import time
from collections import deque
from pathlib import Path

import typer

from nicer_stream.cli.common import DROP_HELP, parse_drop, user_errors
from nicer_stream.errors import UserError


@user_errors
def priors(
    source: str = typer.Option(..., "--source", help="Source URI, e.g. replica:/data/room0"),
    provider: str = typer.Option(
        ..., "--provider", help="Depth/normal provider: none, oracle, omnidata[:PATH_OR_HUB], depth-anything[:MODEL]"
    ),
    out: Path = typer.Option(..., "--out", help="Cache directory to write"),
    flow: str = typer.Option("dis", "--flow", help="Flow provider: dis, oracle, raft, none"),
    flow_gap: int = typer.Option(1, "--flow-gap", help="Flow between each frame and its previous K frames, both ways"),
    max_side: int | None = typer.Option(None, "--max-side", help="Resize so the longer side is at most N px"),
    stride: int = typer.Option(1, "--stride", help="Keep every N-th frame"),
    start: int = typer.Option(0, "--start", help="Skip this many input frames"),
    drop: str | None = typer.Option(None, "--drop", help=DROP_HELP),
    max_frames: int | None = typer.Option(None, "--max-frames", help="Stop after N kept frames"),
    device: str = typer.Option("cpu", "--device", help="Torch device for network providers"),
) -> None:
    """Precompute depth/normal and flow priors for a source into a cache directory (read back with cache:DIR)."""
    from nicer_stream.priors import make_depth_normal_provider, make_flow_provider
    from nicer_stream.priors.cache import FORMAT_VERSION, CacheMeta, CacheWriter
    from sources import open_source
    from sources.base import SourceOptions

    if flow_gap < 0:
        raise UserError("--flow-gap must be >= 0 (0: no flow)")
    if provider.startswith("cache:") or flow.startswith("cache:"):
        raise UserError("nicer-stream priors writes a cache; give a computing provider, not cache:DIR")
    opts = SourceOptions(start=start, stride=stride, drop=parse_drop(drop), max_frames=max_frames, max_side=max_side)
    src = open_source(source, opts)
    dn_provider = make_depth_normal_provider(provider, device=device)
    flow_provider = make_flow_provider(flow, device=device)
    try:
        total = f"/{len(src)}"
    except TypeError:
        total = ""
    writer = None
    recent: deque = deque(maxlen=flow_gap)
    for k, frame in enumerate(src):
        t0 = time.perf_counter()
        dn = dn_provider.predict(frame)
        t1 = time.perf_counter()
        if writer is None:  # only once the first prediction worked: no half-made cache on errors
            meta = CacheMeta(FORMAT_VERSION, dn_provider.name, flow_provider.name, frame.width, frame.height, source)
            writer = CacheWriter(out, meta)
        writer.write_depth_normal(frame.index, dn)
        n_flows = 0
        if flow_provider.active:
            for prev in recent:
                for f in flow_provider.flow_both(prev, frame):
                    writer.write_flow(f)
                    n_flows += 1
        recent.append(frame)
        typer.echo(
            f"frame {k + 1}{total} (index {frame.index}): {dn_provider.name} {t1 - t0:.2f} s, "
            f"{n_flows} flows ({flow_provider.name}) {time.perf_counter() - t1:.2f} s"
        )
    if writer is None:
        raise UserError(f"source {source} gave no frames: check --start/--max-frames and the path")
    typer.echo(f"wrote prior cache {out} (read it with --priors cache:{out} --flow cache:{out})")
