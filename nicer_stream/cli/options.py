"""The options `run`, `map` and `batch` share: each defined once (flag, default, help), and the
checks of their values, made before anything is read or written (one line naming the flag and
the accepted range, exit 2)."""
from __future__ import annotations

import math
from dataclasses import replace

import typer

from nicer_stream.cli.common import DROP_HELP, parse_drop, parse_intrinsics
from nicer_stream.errors import UserError

MIN_SIDE = 32
"""The smallest --max-side: below a few tens of pixels the flow and the frontend have nothing to match."""

SOURCE_HELP = ("Source URI: replica:PATH, tum:PATH, 7scenes:PATH, folder:PATH, video:FILE, mcap:FILE[?topic=T], "
               "synthetic:NAME (e.g. synthetic:room?frames=40).")
PRIORS = typer.Option("auto", "--priors", help=(
    "Depth/normal priors: auto (learned weights if present, else stereo), stereo, none, oracle (GT with a "
    "monocular network's errors, evaluation only), oracle:clean (near GT, debugging), cache:DIR, omnidata, "
    "depth-anything."))
PRESET = typer.Option("fast", "--preset", help="Config preset: fast (2-core CPU) or paper.")
CONFIG = typer.Option(None, "--config", help="A .toml/.json file overriding preset fields.")
FLOW = typer.Option(None, "--flow", help="Flow prior: dis, oracle (GT, evaluation only), none, cache:DIR "
                                         "(default: oracle with oracle:clean priors, else dis).")
DEVICE = typer.Option("cpu", "--device", help="torch device, e.g. cpu, cuda or cuda:1.")
MAX_FRAMES = typer.Option(None, "--max-frames", help="Stop after N frames (counted after --start, --stride and --drop).")
STRIDE = typer.Option(1, "--stride", help="Keep every N-th input frame.")
START = typer.Option(0, "--start", help="Skip the first N input frames.")
DROP = typer.Option(None, "--drop", help=DROP_HELP)
MAX_SIDE = typer.Option(None, "--max-side", help=f"Resize so the longer side is at most N pixels, N >= {MIN_SIDE} "
                                                 "(default: the preset's).")
INTRINSICS = typer.Option(None, "--intrinsics", help="fx,fy,cx,cy in pixels at the original image size "
                                                     "(fx, fy > 0), instead of the source's.")
SINK = typer.Option([], "--sink", help="rerun (viewer), rerun:FILE.rrd, mcap:FILE.mcap; repeatable. A bare 'rerun' "
                                       "with no viewer writes OUT/recording.rrd.")
RENDER_EVERY = typer.Option(10, "--render-every", help="Render (and evaluate) every N-th frame at the end, N >= 1; "
                                                       "their images are kept until then.")


def source_options(start: int = 0, stride: int = 1, drop: str | None = None, max_frames: int | None = None,
                   max_side: int | None = None, intrinsics: str | None = None):
    """The checked `SourceOptions` of the flags choosing a source's frames, as typed (--drop A:B,
    --intrinsics fx,fy,cx,cy at the original image size); a value out of range is a one-line
    UserError naming its flag."""
    from sources.base import SourceOptions

    if max_side is not None and max_side < MIN_SIDE:
        raise UserError(f"--max-side must be an integer >= {MIN_SIDE} (pixels), got {max_side}")
    intr = parse_intrinsics(intrinsics)
    if intr is not None and not (all(map(math.isfinite, intr)) and intr[0] > 0 and intr[1] > 0):
        raise UserError(f"--intrinsics must be fx,fy,cx,cy with fx, fy > 0 and cx, cy finite (pixels), "
                        f"got '{intrinsics}'")
    return SourceOptions(start=start, stride=stride, drop=parse_drop(drop), max_frames=max_frames,
                         max_side=max_side, intrinsics=intr)


def check_device(device: str) -> str:
    """`device` if torch can parse it, else a one-line UserError."""
    import torch

    try:
        torch.device(device)
    except (RuntimeError, ValueError):
        raise UserError(f"--device must be a torch device such as cpu, cuda or cuda:0, got '{device}'") from None
    return device


def at_least(flag: str, value: float | None, low: float, note: str = "") -> None:
    """A one-line UserError unless `value` is None or >= `low`."""
    if value is not None and value < low:
        raise UserError(f"{flag} must be >= {low}{note}, got {value}")


def run_request(source: str, out, source_opts, log_images_every: int = 10, log_image_side: int = 320,
                **fields):
    """The checked `RunRequest` of a run of `source` into `out`: `fields` are its other fields as
    typed (sinks as given: a bare 'rerun' and the --log-images-every / --log-image-side query are
    resolved here); a value out of range is a one-line UserError naming its flag."""
    from pathlib import Path

    from nicer_stream.cli.sink_specs import resolve_sinks
    from nicer_stream.runtime.slam_run import RunRequest

    req = RunRequest(source=source, out_dir=Path(out), source_opts=source_opts, **fields)
    if req.render_every < 1 or req.max_renders < 0:
        raise UserError(f"--render-every must be at least 1 and --max-renders at least 0 (0: no cap), "
                        f"got {req.render_every} and {req.max_renders}")
    at_least("--live-mesh-every", req.live_mesh_every, 0, " (0: only the final mesh)")
    if req.mapping_worker not in ("auto", "on", "off"):
        raise UserError(f"--mapping-worker must be auto, on or off, got {req.mapping_worker!r}")
    return replace(req, sinks=resolve_sinks(list(req.sinks), Path(out), log_images_every, log_image_side),
                   device=check_device(req.device))
