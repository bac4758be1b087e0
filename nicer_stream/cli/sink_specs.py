"""`--sink` specs as given -> the specs a run opens (a headless 'rerun' becomes a file; the
--log-images-every / --log-image-side query added to each spec without one)."""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import typer


def resolve_sinks(sinks: list[str], out: Path, images_every: int = 1, image_side: int = 0) -> tuple[str, ...]:
    """A bare 'rerun' becomes a file in OUT when no viewer can be spawned (headless); each spec
    without a query of its own gets the image stride and size (sinks/options.py)."""
    from sinks.options import SinkOptions

    query = SinkOptions(images_every, image_side or None).query()
    res = []
    for s in sinks:
        if s == "rerun" and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) and not shutil.which("rerun-viewer"):
            s = f"rerun:{out / 'recording.rrd'}"
            typer.echo(f"no display for a Rerun viewer: recording to {s[6:]}", err=True)
        res.append(s if "?" in s else ",".join(p + query for p in s.split(",") if p.strip()))
    return tuple(res)
