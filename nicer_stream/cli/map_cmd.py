"""`nicer-stream map`: mapping with known poses."""
from __future__ import annotations

from pathlib import Path

import typer

from nicer_stream.cli import options as o
from nicer_stream.cli.common import user_errors
from nicer_stream.errors import UserError

POSES_HELP = "A TUM trajectory file (one line per frame), or 'gt' for the source's ground-truth poses (evaluation only)."
PRIORS_HELP = ("Depth/normal priors: auto (learned weights if present, else none), none, oracle (GT with a monocular "
               "network's errors, evaluation only), oracle:clean (near GT, debugging), cache:DIR, omnidata, depth-anything.")


@user_errors
def map_command(
    source: str = typer.Option(..., "--source", help=o.SOURCE_HELP),
    out: Path = typer.Option(..., "--out", help="Output directory."),
    poses: str = typer.Option(..., "--poses", help=POSES_HELP),
    priors: str = typer.Option("auto", "--priors", help=PRIORS_HELP),
    flow: str = o.FLOW,
    preset: str = o.PRESET,
    config: str = o.CONFIG,
    iters: int = typer.Option(None, "--iters", help="Mapping iterations, N >= 1 (default: the preset's batch_iters)."),
    minutes: float = typer.Option(None, "--minutes", help="Stop mapping after about this many minutes (> 0)."),
    device: str = o.DEVICE,
    max_side: int = o.MAX_SIDE,
    stride: int = o.STRIDE,
    start: int = o.START,
    drop: str = o.DROP,
    max_frames: int = o.MAX_FRAMES,
    intrinsics: str = o.INTRINSICS,
    render_every: int = typer.Option(None, "--render-every", help="Render and evaluate every N-th frame, N >= 1 (default: at most 20 views, spread evenly)."),
) -> None:
    """Fit the neural scene to frames with known poses; writes trajectory, mesh, renders, summary (and eval.json with GT)."""
    from nicer_stream.cli.run_report import evaluate_and_print
    from nicer_stream.runtime.map_known_poses import MapRequest, run_map

    o.at_least("--iters", iters, 1)
    o.at_least("--render-every", render_every, 1)
    if minutes is not None and not minutes > 0:
        raise UserError(f"--minutes must be > 0, got {minutes}")
    if priors == "stereo":
        raise UserError("--priors stereo needs the SLAM's poses: use `nicer-stream run` (map takes per-frame priors)")
    opts = o.source_options(start=start, stride=stride, drop=drop, max_frames=max_frames, max_side=max_side,
                            intrinsics=intrinsics)
    out_dir = run_map(MapRequest(source=source, out_dir=out, poses=poses, priors=priors, flow=flow,
                                 preset=preset, config_file=config, iters=iters, minutes=minutes,
                                 device=o.check_device(device), render_every=render_every, source_opts=opts))
    evaluate_and_print(out_dir, source, opts)
