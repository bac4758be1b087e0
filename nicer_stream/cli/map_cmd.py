"""`nicer-stream map`: mapping with known poses."""
from __future__ import annotations

from pathlib import Path

import typer

from nicer_stream.cli.common import DROP_HELP, parse_drop, parse_intrinsics, user_errors


def map_command(
    source: str = typer.Option(..., "--source", help="Source URI, e.g. replica:PATH, tum:PATH, synthetic:room."),
    out: Path = typer.Option(..., "--out", help="Output directory."),
    poses: str = typer.Option("gt", "--poses", help="'gt' (the source's poses) or a TUM trajectory file (one line per frame)."),
    priors: str = typer.Option("oracle", "--priors", help="Depth/normal priors: oracle, oracle:clean, none, cache:DIR, omnidata, depth-anything."),
    flow: str = typer.Option(None, "--flow", help="Flow prior: oracle, dis, none, cache:DIR (default: oracle with oracle:clean priors, else dis)."),
    preset: str = typer.Option("fast", "--preset", help="fast (2-core CPU) or paper."),
    config: str = typer.Option(None, "--config", help="A .toml/.json file overriding preset fields."),
    iters: int = typer.Option(None, "--iters", help="Mapping iterations (default: the preset's batch_iters)."),
    minutes: float = typer.Option(None, "--minutes", help="Stop mapping after about this many minutes."),
    device: str = typer.Option("cpu", "--device", help="torch device, e.g. cpu or cuda."),
    max_side: int = typer.Option(None, "--max-side", help="Resize so the longer side is at most N pixels (default: preset)."),
    stride: int = typer.Option(1, "--stride"),
    start: int = typer.Option(0, "--start"),
    drop: str = typer.Option(None, "--drop", help=DROP_HELP),
    max_frames: int = typer.Option(None, "--max-frames"),
    intrinsics: str = typer.Option(None, "--intrinsics", help="fx,fy,cx,cy at the original image size."),
    render_every: int = typer.Option(None, "--render-every", help="Render and evaluate every N-th frame (default: at most 20 views, spread evenly)."),
) -> None:
    """Fit the neural scene to frames with known poses; writes trajectory, mesh, renders, summary (and eval.json with GT)."""
    user_errors(_run)(source, out, poses, priors, flow, preset, config, iters, minutes, device, max_side, stride, start,
                      drop, max_frames, intrinsics, render_every)


def _run(source, out, poses, priors, flow, preset, config, iters, minutes, device, max_side, stride, start, drop, max_frames,
         intrinsics, render_every) -> None:
    from nicer_stream.cli.run_report import evaluate_and_print
    from nicer_stream.runtime.map_known_poses import MapRequest, run_map
    from sources.base import SourceOptions

    opts = SourceOptions(start=start, stride=stride, drop=parse_drop(drop), max_frames=max_frames, max_side=max_side,
                         intrinsics=parse_intrinsics(intrinsics))
    out_dir = run_map(MapRequest(source=source, out_dir=out, poses=poses, priors=priors, flow=flow, preset=preset,
                                 config_file=config, iters=iters, minutes=minutes, device=device, render_every=render_every,
                                 source_opts=opts))
    evaluate_and_print(out_dir, source, opts)
